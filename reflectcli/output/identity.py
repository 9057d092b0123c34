"""What made an output: the scene alone (its hash leaves out the technique and the output
section, so an image pairs with its reference), the technique's parameters (their own
attribute), the --set overrides and a run id per render call.

A frame folder keeps frames of one set of overrides: a render with other overrides than
the frames already there is refused in one line instead of silently mixing them, and
`--resume` skips only frames whose stored scene hash and parameters match this run's.
"""

from __future__ import annotations

import hashlib
import json
import os
import uuid

from ..errors import Problem, Problems
from .exr import frame_problem, header_attributes, read_exr_header
from .log import read_jsonl


def scene_identity(content_hash: str, cfg) -> str:
    """sha256 of the scene alone: its content (objects, mirrors, materials, lights, shading,
    the referenced files' bytes), its name and its camera; not the technique, not output."""
    extra = {"name": cfg.scene.name, "camera": cfg.camera.model_dump(mode="json")}
    return hashlib.sha256((content_hash + json.dumps(extra, sort_keys=True)).encode()
                          ).hexdigest()


def new_run_id() -> str:
    return uuid.uuid4().hex[:12]


def logged_rows(log_path: str) -> dict[str, dict]:
    """The last log row of each frame file in the folder's log (empty if there is none)."""
    if not os.path.exists(log_path):
        return {}
    try:
        rows = read_jsonl(log_path)
    except OSError:
        return {}
    return {r["file"]: r for r in rows if isinstance(r.get("file"), str)}


def check_same_overrides(rows: dict[str, dict], overrides: list[str], folder: str,
                         source: str) -> None:
    """Refuse to mix frames of other --set overrides into `folder`."""
    mine = sorted(overrides)
    for row in rows.values():
        if "overrides" not in row:  # written before rows recorded them: unknown, not refused
            continue
        theirs = sorted(row["overrides"] or [])
        if theirs != mine and os.path.exists(os.path.join(folder, row["file"])):
            shown = " ".join(theirs) if theirs else "no --set"
            raise Problems([Problem(source, "", (
                f"{folder} holds frames rendered with other overrides ({shown}); "
                "use another --out, the same --set, or remove those frames"))])


def matches(row: dict | None, scene_hash: str, parameters: dict,
            defaults: dict | None = None) -> bool:
    """Whether a stored frame was made from this scene with these parameters. `defaults`:
    the technique's parameters at their defaults; a parameter the stored row does not name
    (added to the technique after the frame was made) counts as its default then, so a
    new parameter left at its default does not make --resume render old frames again."""
    if row is None or row.get("scene_hash") != scene_hash:
        return False
    stored = row.get("parameters")
    if defaults is not None and isinstance(stored, dict):
        stored = _with_defaults(stored, defaults)
    return stored == parameters


def _with_defaults(stored: dict, defaults: dict) -> dict:
    """`stored` with the keys it lacks taken from `defaults`, nested dicts likewise."""
    out = dict(stored)
    for key, value in defaults.items():
        if key not in out:
            out[key] = value
        elif isinstance(value, dict) and isinstance(out[key], dict):
            out[key] = _with_defaults(out[key], value)
    return out


def file_matches(exr: str, row: dict, defaults: dict | None = None,
                 size: tuple[int, int] | None = None) -> bool:
    """Whether the EXR at `exr` is the frame its log row describes: the size the row
    logged, and the scene hash, frame and parameters in its header (a parameter one of them
    does not name counts as its default, as in `matches`), and with `size` (width, height)
    a header of a frame that size (output/exr.frame_problem: a header claiming more is
    never read). A frame whose file was replaced after its row was written (a run killed
    between the two, a copy, a truncated file, a damaged header) is rendered again by
    --resume, not kept."""
    try:
        if "exr_bytes" in row and os.path.getsize(exr) != row["exr_bytes"]:
            return False
    except OSError:
        return False
    spec = read_exr_header(exr)
    if spec is None or (size is not None and frame_problem(spec, *size) is not None):
        return False
    header = header_attributes(spec)
    try:
        parameters = json.loads(header.get("reflect:parameters", ""))
    except ValueError:
        return False
    logged = row.get("parameters")
    if defaults is not None and isinstance(parameters, dict) and isinstance(logged, dict):
        parameters, logged = _with_defaults(parameters, defaults), _with_defaults(logged,
                                                                                  defaults)
    return (header.get("reflect:scene_hash") == row.get("scene_hash")
            and header.get("reflect:frame") == str(row.get("frame")) and parameters == logged)
