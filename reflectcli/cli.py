"""Command line: parse arguments, call the api, print, set exit codes. Nothing else."""

from __future__ import annotations

import atexit
import logging
import math
import os
import signal
import sys

try:  # Ctrl-C while the command line itself is still importing exits as any interrupt does
    import click

    from . import __version__
    from .errors import Problems
except KeyboardInterrupt:
    sys.stderr.write("interrupted\n")
    raise SystemExit(130) from None

EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130
EXIT_WRITE_FAILED = 1


_interrupted_exit: list[bool] = []


def _exit_interrupted() -> None:
    """Leave with exit code 130 (the caller has said what was kept)."""
    _interrupted_exit.append(True)
    sys.exit(EXIT_INTERRUPTED)


def _keep_exit_code_130() -> None:
    """atexit, registered first so that it runs last. CPython ends a process by re-raising
    SIGINT (exit status -2), whatever sys.exit said, once a KeyboardInterrupt has passed out
    of code run through its C API (a Ctrl-C during a numba compile does). An interrupted run
    promises 130: flush what is buffered and leave with it."""
    if _interrupted_exit:
        logging.shutdown()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(EXIT_INTERRUPTED)


def _fail(problems: Problems, stream=None) -> None:
    for p in problems.problems:
        click.echo(str(p), err=stream is None)
    sys.exit(EXIT_BAD_INPUT)


class _UsageError(click.ClickException):
    """A click argument error as one line (`reflect render: --threads: 'abc' is not a valid
    integer`), not click's usage text plus "Try --help" plus the error."""

    exit_code = EXIT_BAD_INPUT

    def show(self, file=None) -> None:
        click.echo(self.message, err=True)


def _one_line(e: click.UsageError, parent: click.Context | None = None,
              name: str | None = None) -> _UsageError:
    """`parent` and `name`: the command's, when the error has no context (the parser's)."""
    path = (e.ctx.command_path if e.ctx is not None
            else f"{parent.command_path} {name}" if parent is not None else "")
    # "reflect", whatever name the program was started by (tests: CliRunner's "cli")
    where = " ".join(["reflect", *path.split()[1:]])
    param = getattr(e, "param", None)
    if isinstance(e, click.BadParameter) and param is not None:
        hint = ("/".join(param.opts) if isinstance(param, click.Option)
                else param.human_readable_name)
        message = "missing" if isinstance(e, click.MissingParameter) else e.message
        return _UsageError(f"{where}: {hint}: {message}".rstrip("."))
    return _UsageError(f"{where}: {e.format_message()}".rstrip("."))


# click >= 8.2 asks for help with a UsageError subclass (a group run with no command)
_HELP = getattr(click.exceptions, "NoArgsIsHelpError", ())


class _OneLineArguments:
    """A command's or group's argument errors in one line (`_one_line`)."""

    def make_context(self, info_name, args, parent=None, **extra) -> click.Context:
        try:
            return super().make_context(info_name, args, parent, **extra)
        except _HELP:
            raise
        except click.UsageError as e:
            raise _one_line(e, parent, info_name) from None


class _OneLineCommand(_OneLineArguments, click.Command):
    pass


class _OneLineGroup(_OneLineArguments, click.Group):
    command_class = _OneLineCommand
    group_class = type  # a group's subgroups are of this class too

    def resolve_command(self, ctx: click.Context, args: list[str]):
        try:
            return super().resolve_command(ctx, args)
        except click.UsageError as e:
            raise _one_line(e) from None


def _folder(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    """An empty folder name would quietly mean the working directory or no folder."""
    if value == "":
        raise click.BadParameter("empty folder name ('.' is the working directory)")
    return value


@click.group(cls=_OneLineGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="reflect")
def cli() -> None:
    """Render mirror reflections with several techniques and compare them."""


def _render_options(validating: bool = False):
    """`reflect render`'s options, which `reflect validate` takes too (`validating`): a
    render command line validates as it is, with the word changed."""
    options = [
        click.option("--out", "out", type=click.Path(file_okay=False), callback=_folder,
                     help="output root (default: output.dir)"),
        click.option("--frames", help="frame N, frames A:B (B excluded), or every S-th: "
                                       "A:B:S"),
        click.option("--technique", help="render with this technique instead of the scene's"),
        click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
                     help="override any config field, e.g. technique.max_depth=2 "
                          "(repeatable)"),
        click.option("--preview/--no-preview", default=None,
                     help="accepted, so a render command line validates unchanged; adds "
                          "no check (the PNG names are checked either way)" if validating else
                          "also write an sRGB PNG per frame"),
        click.option("--threads", type=int, help="worker threads (default: all cores)"),
        click.option("--resume", is_flag=True,
                     help="accepted, so a render command line validates unchanged; adds "
                          "no check" if validating else
                          "skip frames already rendered with the same scene and "
                          "parameters (their EXR as logged)"),
        click.option("--cache", type=click.Path(file_okay=False), callback=_folder,
                     help="map cache folder (default: .reflect-cache/ beside the scene)"),
    ]

    def decorate(command):
        for option in reversed(options):
            command = option(command)
        return command

    return decorate


@cli.command()
@click.argument("scene", type=click.Path(dir_okay=False))
@_render_options()
def render(scene, out, frames, technique, overrides, preview, threads, resume, cache) -> None:
    """Render SCENE (a TOML file) to out/<scene>/<technique>/frame_NNNN.exr."""
    from . import api

    progress = None
    done: list[str] = []
    try:
        # render's checks before it writes anything: these, then write_frames' (folders);
        # `reflect validate` runs the same (validate.py)
        opened, selected = api.open_render(scene, frames=frames, technique=technique,
                                           overrides=overrides, threads=threads, cache=cache)
        warning = api.frames_past_end(frames, opened.frame_count)
        if warning:
            click.echo(warning, err=True)
        if len(selected) > 1:
            progress = _open_bar(len(selected), "frames")

        def on_frame(index: int, path: str) -> None:
            done.append(path)
            if progress is not None:
                progress.update(1)

        result = opened.write_frames(selected, out=out, preview=preview, resume=resume,
                                     on_frame=on_frame, overlap_writes=True)
    except Problems as e:
        _fail(e)
    except KeyboardInterrupt:
        if progress is not None:
            progress.__exit__(None, None, None)
        click.echo(f"\ninterrupted: {len(done)} completed frame(s) kept", err=True)
        _exit_interrupted()
    except OSError as e:
        _write_failed(e)
    if progress is not None:
        progress.__exit__(None, None, None)
    skipped = f", {len(result.skipped)} skipped (--resume)" if result.skipped else ""
    click.echo(f"wrote {len(result.written)} frame(s) to {result.folder}{skipped}")
    if result.timing_warning:
        click.echo(f"warning: {result.timing_warning} (timings-summary.json)", err=True)


def _write_failed(e: OSError) -> None:
    """A write failure (full disk, read-only folder): one line naming the file, exit 1."""
    from .output.failures import one_line

    click.echo(f"\n{one_line(e)}" if sys.stderr.isatty() else one_line(e), err=True)
    sys.exit(EXIT_WRITE_FAILED)


def _open_bar(length: int, label: str):
    """An entered progress bar on stderr, or None when stderr is not a terminal."""
    if not sys.stderr.isatty():
        return None
    bar = click.progressbar(length=length, label=label, file=sys.stderr)
    bar.__enter__()
    return bar


@cli.command("precompute-maps")
@click.argument("scene", type=click.Path(dir_okay=False))
@click.option("--technique", help="a map-based technique instead of the scene's")
@click.option(
    "--set",
    "overrides",
    multiple=True,
    metavar="KEY=VALUE",
    help="override any config field (repeatable)",
)
@click.option(
    "--cache",
    type=click.Path(file_okay=False), callback=_folder,
    help="map cache folder (default: .reflect-cache/ beside the scene)",
)
@click.option("--threads", type=int, help="worker threads (default: all cores)")
def precompute_maps(scene, technique, overrides, cache, threads) -> None:
    """Capture the maps SCENE's technique needs into the cache (cached ones are kept)."""
    from . import api

    bar: dict = {}

    def on_progress(done: int, total: int) -> None:
        if "bar" not in bar:
            bar["bar"] = _open_bar(total, "capturing maps")
            bar["done"] = 0
        if bar["bar"] is not None:
            bar["bar"].update(done - bar["done"])
            bar["done"] = done

    def on_map(record: dict) -> None:
        if bar.get("bar") is not None:
            bar["bar"].__exit__(None, None, None)
        bar.pop("bar", None)
        click.echo(
            f"{record.status:>8}  {record.mirror}  {record.seconds:.2f} s  "
            f"{record.path}"
        )

    try:
        api.check_technique(technique)
        result = api.precompute(
            scene,
            technique=technique,
            overrides=overrides,
            cache=cache,
            threads=threads,
            on_map=on_map,
            on_progress=on_progress,
        )
    except Problems as e:
        _fail(e)
    except KeyboardInterrupt:
        click.echo("\ninterrupted: maps already stored are kept", err=True)
        _exit_interrupted()
    except OSError as e:
        _write_failed(e)
    captured = sum(1 for m in result.maps if m.status == "captured")
    click.echo(f"{captured} captured, {len(result.maps) - captured} cached in {result.cache}")


@cli.group()
def cache() -> None:
    """Manage the precomputed-map cache."""


@cache.command("clear")
@click.argument("scene", required=False, type=click.Path(dir_okay=False))
@click.option(
    "--cache",
    "folder",
    type=click.Path(file_okay=False), callback=_folder,
    help="the cache folder (default: .reflect-cache/ beside SCENE)",
)
def cache_clear(scene, folder) -> None:
    """Delete every cached map in SCENE's cache folder (shared by the scenes beside it), or
    in --cache DIR."""
    from . import api

    if folder is None and scene is None:
        click.echo("cache clear: give a SCENE or --cache DIR", err=True)
        sys.exit(EXIT_BAD_INPUT)
    if folder is None:
        from .config.files import display_path, file_problem
        from .config.limits import MAX_TOML_BYTES
        from .errors import Problem

        problem = file_problem(scene, MAX_TOML_BYTES, "scene file")
        if problem is not None:  # a mistyped scene is not an empty cache beside it
            _fail(Problems([Problem(display_path(scene), "", problem)]))
        folder = api.default_cache_dir(scene)
    try:
        cleared = api.clear_cache(folder)
    except OSError as e:
        _write_failed(e)
    temps = (f" and {cleared.temps} temporary file(s) of killed captures"
             if cleared.temps else "")
    click.echo(f"removed {cleared.maps} map(s){temps} from {folder}")


@cli.command()
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--resume", is_flag=True, help="keep the rows already in results.jsonl")
@click.option("--workers", type=int, default=1, show_default=True,
              help="run jobs in this many local processes")
@click.option("--scheduler", metavar="ADDRESS", help="run jobs on a Dask cluster")
@click.option("--threads", type=int, help="numba threads per job")
@click.option("--out", "out", type=click.Path(file_okay=False), callback=_folder,
              help="output folder (default: the bench file's bench.out, or out/bench/<name>)")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="override a config field in every run (repeatable)")
def bench(file, resume, workers, scheduler, threads, out, overrides) -> None:
    """Run the bench matrix in FILE; write results.csv/.jsonl, report.md and plots."""
    from .bench.runner import check_workers, load_bench, run_bench

    progress = None
    try:
        check_workers(workers)  # a bad argument before the bench file is read
        plan = load_bench(file, out, overrides)
        progress = _open_bar(len(plan.jobs), "runs")
        result = run_bench(file, resume=resume, workers=workers, scheduler=scheduler,
                           threads=threads, out=out, overrides=overrides, plan=plan,
                           on_row=(lambda row: progress.update(1)) if progress else None)
    except Problems as e:
        _fail(e)
    except KeyboardInterrupt:
        click.echo("\ninterrupted: finished runs are kept (--resume continues)", err=True)
        _exit_interrupted()
    except OSError as e:
        _write_failed(e)
    finally:
        if progress is not None:
            progress.__exit__(None, None, None)
    click.echo(f"{result.ran} run(s), {result.skipped} kept; results in {result.out}")
    from .bench.runner import timing_warned

    warned = timing_warned(result.rows)
    if warned:
        first = warned[0]
        why = first.get("timing_warning") or first.get("reference_timing_warning")
        click.echo(f"warning: {len(warned)} run(s) timed on too few renders or with no warm-up "
                   "or set against a reference timed at another thread count or on another "
                   f"CPU (e.g. {first.get('run')}: {why}); their frame times and ratios are "
                   "marked in report.md, not figures to quote", err=True)
    from .bench.report import busy_rows

    busy = busy_rows(result.rows)
    if busy:
        click.echo(f"warning: {len(busy)} run(s) timed while the load average exceeded the "
                   f"{busy[0]['cores']} cores + 1 (report.md): their frame times include "
                   "waiting for the cores", err=True)


@cli.command()
@click.argument("first", type=click.Path(dir_okay=False, exists=True))
@click.argument("second", type=click.Path(dir_okay=False, exists=True))
@click.option("--mask-channel", help="also score only pixels where this channel is > 0 in both")
@click.option("--threshold", type=float, default=0.1, show_default=True,
              help="error above which a pixel counts as off")
@click.option("--metrics", "metrics", default="all", show_default=True,
              help="comma-separated: psnr, rmse, max_error, frac_off, relmse, p50, p95, p99, "
                   "flip, flip_ldr, ssim")
def compare(first, second, mask_channel, threshold, metrics) -> None:
    """Score SECOND against FIRST (the reference): PSNR, RMSE, max error, pixels off, relMSE,
    error percentiles, FLIP (HDR and LDR) and SSIM, over the whole image and the mask."""
    from . import api
    from .errors import Problem
    from .metrics import parse_metrics
    from .metrics.compare import format_value

    if not (math.isfinite(threshold) and threshold > 0):
        _fail(Problems([Problem("--threshold", "", f"must be a finite number > 0, got "
                                f"{threshold}")]))
    try:
        chosen = parse_metrics(metrics)
    except ValueError as e:
        _fail(Problems([Problem("--metrics", "", str(e))]))
    try:
        result = api.compare(first, second, metrics=chosen, mask_channel=mask_channel,
                             threshold=threshold)
    except Problems as e:
        _fail(e)
    for warning in result.warnings:
        click.echo(f"warning: {warning}", err=True)
    for scope, values in result.scopes.items():
        click.echo(f"over {scope}")
        for name, value in values.items():
            click.echo(f"{name:<9} {format_value(name, value, threshold)}")


@cli.command()
@click.argument("file", type=click.Path(dir_okay=False))
@_render_options(validating=True)
def validate(file, out, frames, technique, overrides, preview, threads, resume, cache) -> None:
    """Check a scene or config FILE; print `ok` or one line per problem (exit code 2).

    A scene gets every check `reflect render FILE` with the same options makes before it
    writes anything: the options, the scene, its frames, output folder and map cache. A
    bench file is checked as `reflect bench` would check it (with --out, --set, --threads),
    a file without [scene] as an include or section file. Nothing is left on disk: no
    output or cache folder, no lock, no log (a probe folder is made and removed at once
    where a missing folder would be made, as render would make it)."""
    from .validate import RenderOptions, validate_file

    options = RenderOptions(out=out, frames=frames, technique=technique,
                            overrides=tuple(overrides), threads=threads, cache=cache)
    try:
        checked = validate_file(file, options)
    except Problems as e:
        _fail(e, stream=sys.stdout)
    click.echo("ok")
    for note in checked.notes:
        click.echo(note, err=True)


@cli.command()
def schema() -> None:
    """Print the JSON schema of scene files (for editors; docs/scene-reference.md)."""
    import json

    from .reference import scene_schema

    click.echo(json.dumps(scene_schema(), indent=2))


@cli.command()
def techniques() -> None:
    """List the techniques with their parameters and defaults."""
    from .techniques.params import parameter_table
    from .techniques.registry import PARAMS, technique_doc

    for name, params in PARAMS.items():
        doc = technique_doc(name).strip()
        summary = " ".join(doc.split("\n\n")[0].split())
        click.echo(f"{name}: {summary}")
        rows = parameter_table(params)
        if not rows:
            click.echo("    (no parameters)")
        width = max((len(r[0]) for r in rows), default=0)
        type_width = max((len(r[1]) for r in rows), default=0)
        for pname, ptype, default, allowed, desc in rows:
            click.echo(f"    {pname:<{width}}  {ptype:<{type_width}}  = {default}"
                       + (f"  in {allowed}" if allowed.startswith(("[", "(")) else
                          f"  {allowed}" if allowed else "")
                       + (f"  ({desc})" if desc else ""))
        click.echo("")


def main() -> None:
    # keep numba's threads to the cores we have unless the user says otherwise
    os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
    from .environment import environment_problems

    found = environment_problems()  # before numba loads: its failure is a traceback
    if found:
        for problem in found:
            click.echo(str(problem), err=True)
        sys.exit(EXIT_BAD_INPUT)
    # notices (cache recaptures, what was captured) as single lines on stderr
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(message)s"))
    logger = logging.getLogger("reflect")
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    from . import interrupts

    atexit.register(_keep_exit_code_130)
    # SIGTERM is handled like Ctrl-C (same exit, same promises); both are also remembered, so
    # one swallowed by a C callback (a numba compile) still stops the run at the next frame
    signal.signal(signal.SIGTERM, interrupts.on_signal)
    signal.signal(signal.SIGINT, interrupts.on_signal)
    sys.unraisablehook = _quiet_interrupts
    try:
        code = cli(prog_name="reflect", standalone_mode=False)
    except KeyboardInterrupt:  # during start-up (imports, loading), before a command's handler
        click.echo("\ninterrupted", err=True)
        _exit_interrupted()
    except click.exceptions.Abort:
        click.echo("\ninterrupted", err=True)
        _exit_interrupted()
    except click.ClickException as e:
        e.show()
        sys.exit(e.exit_code)
    except Exception:
        if not interrupts.requested.is_set():
            raise
        # an interrupt inside a numba compile can leave it failing in its own words
        click.echo("\ninterrupted", err=True)
        _exit_interrupted()
    sys.exit(code if isinstance(code, int) else 0)


def _quiet_interrupts(unraisable) -> None:
    """A Ctrl-C dropped inside a C callback is no traceback for the user: it is recorded
    (reflectcli/interrupts.py) and ends the run at the next frame."""
    if isinstance(unraisable.exc_value, KeyboardInterrupt):
        return
    sys.__unraisablehook__(unraisable)


if __name__ == "__main__":
    main()
