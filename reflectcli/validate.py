"""`reflect validate`: a whole scene, a bench file, or a section file / technique preset
(camera, mirrors, technique, ...).

A scene goes through every check `render` runs before it writes anything, through render's
own code (api.open_render, then OpenedScene.check_output: the scene build, the folders, the
cache), with render's options (`--out`, `--set`, `--technique`, `--frames`, `--cache`,
`--threads`), so the two always agree and validate writes nothing. A file with `[scene]` is
a scene. A file without one is an include fragment, section file or preset, whatever
sections it holds (`[camera]` and `[materials]` are a common fragment): each section is
checked as a scene would check it, and stderr says that `render` refuses the file by itself
(`scene: required`), so that it is the scene including it that renders (and validates) as a
whole. Checked as a scene, a fragment failed on `scene: required` and on references to what
the including scene defines. Render's options describe a render of a scene, so a fragment
given one is refused in one line; a bench file takes the options `reflect bench` shares with
render (`--out`, `--set`, `--threads`) and refuses the others.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from pydantic import ValidationError, create_model

from .config.base import Strict
from .config.files import display_path
from .config.load import load_raw, validation_problems
from .errors import Problem, Problems


@dataclass(frozen=True)
class RenderOptions:
    """The options of `reflect render` that change what it checks (None / empty: not given,
    render's defaults). `--preview` and `--resume` change no check (validate takes them, so
    that a render command line validates as it is, and ignores them)."""

    out: str | None = None
    frames: str | None = None
    technique: str | None = None
    overrides: tuple[str, ...] = ()
    threads: int | None = None
    cache: str | None = None

    def given(self) -> list[str]:
        """The options given, as the command line names them."""
        named = (("--out", self.out), ("--frames", self.frames),
                 ("--technique", self.technique), ("--set", self.overrides or None),
                 ("--threads", self.threads), ("--cache", self.cache))
        return [name for name, value in named if value is not None]


# the render options a bench file takes too, with the same meaning (`reflect bench`)
BENCH_OPTIONS = ("--out", "--set", "--threads")


@dataclass
class Validated:
    """What a file was checked as (`kind`: "scene", "bench file, N run(s)" or a section
    file's note) and the notes for stderr (render's own warnings, what the file is)."""

    kind: str
    notes: list[str] = field(default_factory=list)


def validate_file(path: str, options: RenderOptions | None = None) -> Validated:
    """Raise Problems for everything wrong with the file (rendered with `options`); else
    what it was checked as."""
    from . import api

    options = options or RenderOptions()
    api.check_technique(options.technique)  # render's first check, before any file is read
    prov: dict = {}
    display = display_path(path)
    raw = load_raw(path, prov)
    if not raw:
        raise Problems([Problem(display, "", "empty file: no keys (a scene needs [scene] "
                                             "and [camera])")])
    if "bench" in raw:
        return _validate_bench(path, display, options)
    from .techniques.registry import scene_model

    fields = scene_model().model_fields
    if "scene" in raw or not set(raw) <= set(fields):  # unknown keys: the scene's lines
        opened, frames = api.open_render(path, frames=options.frames,
                                         technique=options.technique,
                                         overrides=options.overrides,
                                         threads=options.threads, cache=options.cache)
        opened.check_output(options.out, frames)
        warning = api.frames_past_end(options.frames, opened.frame_count)
        return Validated("scene", [warning] if warning else [])
    section = create_model("Section", __base__=Strict,
                           **{key: (fields[key].annotation, fields[key]) for key in raw})
    try:
        section.model_validate(raw)
    except ValidationError as e:
        raise Problems(validation_problems(e, raw, prov, display, section)) from None
    if options.given():
        raise Problems([Problem(display, "scene", (
            f"required for {', '.join(options.given())} (render's options apply to a scene; "
            "this file has no [scene]: an include or section file); validate the scene "
            "that includes it with them"))])
    kind = (f"section or include file ({', '.join(raw)}): it has no [scene], so it cannot "
            "be rendered by itself (render refuses it: scene: required); validate the scene "
            "that includes it")
    return Validated(kind, [f"checked as a {kind}"])


def _validate_bench(path: str, display: str, options: RenderOptions) -> Validated:
    """A bench file as `reflect bench` reads it with the options it shares with render."""
    from . import api
    from .bench.runner import load_bench

    other = [name for name in options.given() if name not in BENCH_OPTIONS]
    if other:
        raise Problems([Problem(other[0], "", (
            f"applies to a scene file, not to the bench file {display} (the options bench "
            f"shares with render: {', '.join(BENCH_OPTIONS)})"))])
    plan = load_bench(path, options.out, options.overrides)
    api.check_threads(options.threads)  # bench's order: the file, then --threads
    kind = f"bench file, {len(plan.jobs)} run(s)"
    return Validated(kind, [f"checked as a {kind}"])
