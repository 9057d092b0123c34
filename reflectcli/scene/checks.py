"""Checks a schema cannot express: references, files, degenerate mirrors, cameras on mirrors.

They live above config/ because the geometric ones need the mirror geometry and the camera.
"""

from __future__ import annotations

import math
import os

import numpy as np

from ..camera import Camera, camera_from_config
from ..config.files import file_problem
from ..config.limits import MAX_FOV_Y, MAX_MESH_BYTES, MAX_TEXTURE_BYTES, MIN_FOV_Y
from ..config.load import origin
from ..config.scene import SceneConfig
from ..errors import Problem
from .mirrors import mirror_corners, profile_normals, profile_points


def _resolve(source: str, path: str) -> str:
    return os.path.join(os.path.dirname(os.path.abspath(source)), path)


def _unreadable(source: str, path: str, limit: int) -> str | None:
    reason = file_problem(_resolve(source, path), limit)
    return None if reason is None else reason + (f": {path}" if "\0" not in path else "")


def semantic_problems(cfg: SceneConfig, source: str, prov: dict, display: str) -> list[Problem]:
    problems: list[Problem] = []

    def add(loc: tuple, message: str, related: tuple = ()) -> None:
        """`related`: the other fields the check reads; one that `--set` gave blames it (the
        file's value at `loc` is not what made the pair wrong)."""
        file = origin(prov, loc, display)
        if any(origin(prov, other, display) == "--set" for other in related):
            file = "--set"
        problems.append(Problem(file, ".".join(str(p) for p in loc), message))

    names: dict[str, str] = {}
    for section, items in (("objects", cfg.objects), ("mirrors", cfg.mirrors)):
        for i, item in enumerate(items):
            if item.name in names:
                add((section, i, "name"), f"'{item.name}' is already used by {names[item.name]}")
            names[item.name] = f"{section}.{i}"
    for i, obj in enumerate(cfg.objects):
        if obj.material not in cfg.materials:
            known = ", ".join(sorted(cfg.materials)) or "none defined"
            add(("objects", i, "material"), f"unknown material '{obj.material}' (known: {known})")
        if obj.shape == "mesh" and (why := _unreadable(source, obj.path, MAX_MESH_BYTES)):
            add(("objects", i, "path"), why)
        if obj.shape in ("box", "room", "clutter") and not all(
            a < b for a, b in zip(obj.min, obj.max, strict=True)
        ):
            add(("objects", i, "max"), "must exceed min on every axis", (("objects", i, "min"),))
    for name, mat in cfg.materials.items():
        if mat.kind == "texture" and (why := _unreadable(source, mat.path, MAX_TEXTURE_BYTES)):
            add(("materials", name, "path"), why)
    planes = []
    for j, m in enumerate(cfg.mirrors):
        if m.shape == "mesh" and (why := _unreadable(source, m.path, MAX_MESH_BYTES)):
            add(("mirrors", j, "path"), why)
        if m.shape in ("cylinder", "cap") and np.linalg.norm(m.axis) == 0:
            add(("mirrors", j, "axis"), "must not be zero")
        if m.shape == "extrusion":
            points = profile_points(m.profile)
            if len(points) < 2:
                add(("mirrors", j, "profile"),
                    f"needs at least 2 distinct points (has {len(points)})")
            else:
                try:
                    profile_normals(points)
                except ValueError as e:
                    add(("mirrors", j, "profile"), str(e))
        if m.shape == "rectangle":
            n, up = np.array(m.normal, float), np.array(m.up, float)
            if np.linalg.norm(n) == 0:
                add(("mirrors", j, "normal"), "must not be zero")
                continue
            if np.linalg.norm(np.cross(n, up)) <= 1e-9 * np.linalg.norm(n) * np.linalg.norm(up):
                add(("mirrors", j, "up"), "must not be parallel to the normal",
                    (("mirrors", j, "normal"),))
                continue
        if not m.planar:
            continue
        c = mirror_corners(m)
        n = np.cross(c[1] - c[0], c[3] - c[0])
        n2 = np.cross(c[3] - c[2], c[1] - c[2])
        scale = max(np.ptp(c, axis=0).max(), 1e-30)
        field = "corners" if m.shape == "quad" else "size"
        if np.linalg.norm(n) <= 1e-9 * scale**2 or np.linalg.norm(n2) <= 1e-9 * scale**2:
            add(("mirrors", j, field), "mirror has zero area")
            continue
        unit = n / np.linalg.norm(n)
        if abs(unit @ (c[2] - c[0])) > 1e-6 * scale:
            add(("mirrors", j, field), "corners are not coplanar")
            continue
        planes.append((j, m.name, unit, float(-unit @ c[0]), scale))
    eye, target, up = map(np.array, (cfg.camera.eye, cfg.camera.target, cfg.camera.up))
    if np.linalg.norm(eye - target) == 0:
        add(("camera", "target"), "must differ from camera.eye", (("camera", "eye"),))
    elif np.linalg.norm(np.cross(target - eye, up)) == 0:
        add(("camera", "up"), "must not be parallel to the viewing direction",
            (("camera", "eye"), ("camera", "target")))
    else:
        _camera_frame_problems(cfg, planes, add)
    return problems


def degenerate_view(camera: Camera) -> str | None:
    """Why no image can be made from `camera` (its eye on its target, its up along the view
    or zero, its field of view outside the documented range), or None. A path's frames are
    interpolated between keys, so each frame can fail where no key does: keys that swap eye
    and target meet halfway, opposite ups cancel, Catmull-Rom overshoots a fov."""
    # plain floats: this runs for each of up to 100,000 frames, and numpy's small-array
    # calls cost more than the arithmetic
    vx, vy, vz = (float(t) - float(e) for t, e in zip(camera.target, camera.eye, strict=True))
    ux, uy, uz = (float(u) for u in camera.up)
    length = math.sqrt(vx * vx + vy * vy + vz * vz)
    if length == 0:
        return "eye and target coincide"
    cx, cy, cz = vy * uz - vz * uy, vz * ux - vx * uz, vx * uy - vy * ux
    if math.sqrt(cx * cx + cy * cy + cz * cz) <= 1e-9 * length * math.sqrt(
            ux * ux + uy * uy + uz * uz):
        return "up is zero or parallel to the viewing direction"
    if not MIN_FOV_Y <= camera.fov_y <= MAX_FOV_Y:
        return f"fov_y is {camera.fov_y:.3g} degrees (must be {MIN_FOV_Y}..{MAX_FOV_Y:g})"
    return None


def _camera_frame_problems(cfg: SceneConfig, planes: list, add) -> None:
    """Every frame's camera: a degenerate view (a path's frames; the still camera was
    checked by its fields) and an eye on a mirror's plane; the first frame that fails."""
    path = cfg.camera.path
    if path is None and not planes:
        return
    field = ("camera", "path") if path else ("camera", "eye")
    related = (("camera", "up"), ("camera", "fov_y")) if path else ()  # a key may lack them
    for frame_index in range(cfg.camera.frame_count):
        cam = camera_from_config(cfg.camera, frame_index)
        where = f" at frame {frame_index}" if path else ""
        if path is not None and (why := degenerate_view(cam)) is not None:
            add(field, why + where, related)
            return
        hit = [p for p in planes if abs(p[2] @ cam.eye + p[3]) <= 1e-6 * max(1.0, p[4])]
        if hit:
            add(field, f"eye lies on the plane of mirror '{hit[0][1]}'{where}")
            return
