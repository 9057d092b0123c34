"""Config -> Scene: primitives and mesh files flattened to world-space float32 arrays."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass

import numpy as np

from ..config.mirrors import (
    CylinderMirror,
    ExtrusionMirror,
    MeshMirror,
    SphereMirror,
)
from ..config.objects import TransformKey
from ..config.scene import SceneConfig
from ..errors import Problem, Problems
from ..geometry import trs_matrix
from . import primitives
from .extent import motion_reach, reach, too_far
from .mesh import Mesh, joined_pieces
from .mesh_file import cached_mesh_file as _mesh_file
from .mesh_file import resolve
from .mirrors import extrusion_profile, mirror_corners, mirror_mesh, mirror_plane
from .textures import load_texture
from .types import (
    CHECKER,
    CYLINDER,
    DIRECTIONAL,
    LAMBERT,
    MESH,
    MIRROR_PARAMS,
    PLANAR,
    POINT,
    SOLID,
    SPHERE,
    TEXTURE,
    UNLIT,
    Geometry,
    Lights,
    Materials,
    Mirrors,
    Scene,
    Triangles,
)


def object_mesh(obj, source: str) -> Mesh:
    """The object's mesh in its own (object) space."""
    s = obj.shape
    if s == "quad":
        return primitives.quad(np.array(obj.corners), np.array(obj.uv))
    if s == "box":
        return primitives.box(obj.min, obj.max)
    if s == "room":
        return primitives.room(obj.min, obj.max, faces=obj.faces)
    if s == "sphere":
        if obj.tessellation == "ico":
            return primitives.ico_sphere(obj.radius, obj.subdivisions)
        return primitives.uv_sphere(obj.radius, obj.segments)
    if s == "cylinder":
        return primitives.cylinder(obj.radius, obj.height, obj.segments, caps=obj.caps)
    if s == "cone":
        return primitives.cone(obj.radius, obj.height, obj.segments)
    if s == "pyramid":
        return primitives.pyramid(obj.size, obj.height)
    if s == "torus":
        return primitives.torus(
            obj.major_radius, obj.minor_radius, obj.major_segments, obj.minor_segments
        )
    if s == "teapot":
        from .teapot import teapot

        return teapot(obj.subdivisions)
    if s == "mesh":
        from .fit import fit_mesh

        return fit_mesh(_mesh_file(resolve(source, obj.path)), obj.name, obj.path, obj.fit)
    if s == "clutter":
        from .procedural import music_room_clutter

        return music_room_clutter(obj.triangles, obj.min, obj.max, seed=obj.seed)
    raise AssertionError(s)


@dataclass(frozen=True)
class Pieces:
    """A part's closed pieces (Mesh.pieces) after `without_degenerate`: each triangle's
    piece id (T,) int32 (-1: open) and each piece's world box (K, 6: min x, y, z, max x,
    y, z; NaN for a piece with no triangle left)."""

    ids: np.ndarray
    boxes: np.ndarray

    @staticmethod
    def of(mesh: Mesh, tris: Triangles) -> Pieces:
        """The pieces of `mesh` (without_degenerate's) over its triangles as drawn."""
        count = mesh.piece_count
        ids = (np.full(tris.count, -1, np.int32) if mesh.pieces is None
               else np.ascontiguousarray(mesh.pieces, np.int32))
        return Pieces(ids, piece_boxes(tris.corners, ids, count))


def piece_boxes(corners: np.ndarray, ids: np.ndarray, count: int) -> np.ndarray:
    """(count, 6) float64 world boxes of the pieces `ids` (T,) marks in `corners` (T, 3, 3);
    NaN for a piece with no triangle. Pieces come as runs of triangles: reduced per run,
    then runs of the same piece joined."""
    lo = np.full((count, 3), np.inf)
    hi = np.full((count, 3), -np.inf)
    if count and ids.size:
        starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
        run_ids = ids[starts]
        mine = run_ids >= 0
        points = corners.astype(np.float64)
        np.minimum.at(lo, run_ids[mine], np.minimum.reduceat(points.min(axis=1), starts)[mine])
        np.maximum.at(hi, run_ids[mine], np.maximum.reduceat(points.max(axis=1), starts)[mine])
    boxes = np.concatenate([lo, hi], axis=1)
    boxes[~np.isfinite(boxes).all(axis=1)] = np.nan
    return boxes


def _joined_pieces(parts: list[Pieces]) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(closed_piece (T,) int32, closed_boxes (K, 6)) of parts concatenated in order, their
    ids renumbered after the ones before; (None, None) without any piece."""
    if not any(len(p.boxes) for p in parts):
        return None, None
    return (joined_pieces([(p.ids, len(p.boxes), len(p.ids)) for p in parts]),
            np.concatenate([p.boxes for p in parts]))


def transform_at(obj, frame_index: int) -> np.ndarray:
    """The object's 4x4 world_from_object transform at frame `frame_index`: keyframes
    (`motion`, each at its `frame` index) interpolate linearly, clamped at the ends."""
    if not obj.motion:
        t = obj.transform
        return trs_matrix(t.translate, t.rotate, t.scale)
    keys: list[TransformKey] = obj.motion
    if frame_index <= keys[0].frame or len(keys) == 1:
        k = keys[0]
        return trs_matrix(k.translate, k.rotate, k.scale)
    if frame_index >= keys[-1].frame:
        k = keys[-1]
        return trs_matrix(k.translate, k.rotate, k.scale)
    i = max(j for j in range(len(keys)) if keys[j].frame <= frame_index)
    a, b = keys[i], keys[i + 1]
    u = (frame_index - a.frame) / (b.frame - a.frame)

    def mix(x, y):
        return (1 - u) * np.asarray(x, float) + u * np.asarray(y, float)

    return trs_matrix(mix(a.translate, b.translate), mix(a.rotate, b.rotate), mix(a.scale, b.scale))


def _triangles(mesh: Mesh, material: int, surface: int) -> Triangles:
    n = mesh.triangle_count
    return Triangles(
        mesh.corners.astype(np.float32),
        mesh.uvs.astype(np.float32),
        mesh.normals.astype(np.float32),
        np.full(n, material, np.int32),
        np.full(n, surface, np.int32),
    )


def _concat(parts: list[Triangles]) -> Triangles:
    if not parts:
        return Triangles(
            np.zeros((0, 3, 3), np.float32),
            np.zeros((0, 3, 2), np.float32),
            np.zeros((0, 3, 3), np.float32),
            np.zeros(0, np.int32),
            np.zeros(0, np.int32),
        )
    return Triangles(
        *(np.concatenate([getattr(p, f) for p in parts]) for f in
          ("corners", "uvs", "normals", "material", "surface"))
    )


class TextureError(Exception):
    def __init__(self, material: str, message: str) -> None:
        super().__init__(message)
        self.material, self.message = material, message.splitlines()[0]


def _materials(cfg: SceneConfig, source: str) -> Materials:
    names = list(cfg.materials)
    mat_i = np.zeros((max(len(names), 1), 5), np.int32)
    mat_f = np.zeros((max(len(names), 1), 8), np.float32)
    texels = [np.zeros((1, 3), np.float32)]
    offset = 1
    for k, name in enumerate(names):
        m = cfg.materials[name]
        if m.kind == "solid":
            mat_i[k, 0] = SOLID
            mat_f[k, 0:3] = m.color
        elif m.kind == "checker":
            mat_i[k, 0] = CHECKER
            mat_f[k, 0:3], mat_f[k, 3:6], mat_f[k, 6:8] = m.color0, m.color1, m.scale
        else:
            try:
                img = load_texture(resolve(source, m.path), m.srgb)
            except (OSError, ValueError) as e:
                raise TextureError(name, str(e)) from None
            h, w = img.shape[:2]
            mat_i[k] = (TEXTURE, offset, w, h, 1 if m.filter == "bilinear" else 0)
            mat_f[k, 6:8] = m.scale
            texels.append(img.reshape(-1, 3))
            offset += w * h
    return Materials(names, mat_i, mat_f, np.ascontiguousarray(np.concatenate(texels)))


def _lights(cfg: SceneConfig) -> Lights:
    rows = []
    for light in cfg.lights:
        rgb = np.array(light.color) * light.intensity
        if light.kind == "point":
            rows.append([POINT, *light.position, *rgb])
        else:
            d = np.array(light.direction, float)
            rows.append([DIRECTIONAL, *(d / np.linalg.norm(d)), *rgb])
    return Lights(np.array(rows, np.float32).reshape(-1, 7))


def _mirrors(cfg: SceneConfig) -> Mirrors:
    kinds, params = [], []
    for m in cfg.mirrors:
        p = np.zeros(MIRROR_PARAMS)
        if m.planar:
            kinds.append(PLANAR)
            n, d = mirror_plane(m)
            p = Mirrors.planar_row(n, d, mirror_corners(m))
        elif isinstance(m, SphereMirror):
            kinds.append(SPHERE)
            p = Mirrors.sphere_row(m.center, m.radius)
        elif isinstance(m, CylinderMirror):
            kinds.append(CYLINDER)
            a = np.array(m.axis, float)
            p = Mirrors.cylinder_row(m.origin, a / np.linalg.norm(a), m.radius, m.height)
        else:
            kinds.append(MESH)
        params.append(p)
    k = len(cfg.mirrors)
    return Mirrors(
        [m.name for m in cfg.mirrors],
        np.array(kinds, np.int32).reshape(k),
        np.array([m.reflectance_rgb for m in cfg.mirrors], np.float32).reshape(k, 3),
        np.array([m.base for m in cfg.mirrors], np.float32).reshape(k, 3),
        np.array(params, np.float64).reshape(k, MIRROR_PARAMS),
    )


def scene_hashes(cfg: SceneConfig, source: str) -> tuple[str, str]:
    """(scene hash, content hash): sha256 of the validated config and the bytes of every file
    it references; the content hash leaves out the camera, technique and output, so maps
    captured from the scene stay valid when only those change."""
    files = hashlib.sha256()
    paths = [o.path for o in cfg.objects if o.shape == "mesh"]
    paths += [m.path for m in cfg.materials.values() if m.kind == "texture"]
    paths += [m.path for m in cfg.mirrors if isinstance(m, MeshMirror)]
    for p in paths:
        with open(resolve(source, p), "rb") as f:
            files.update(hashlib.sha256(f.read()).digest())
    dump = cfg.model_dump(mode="json")
    full = hashlib.sha256(json.dumps(dump, sort_keys=True).encode() + files.digest())
    content = {k: dump[k] for k in ("materials", "lights", "objects", "mirrors")}
    content["scene"] = {k: v for k, v in dump["scene"].items() if k != "name"}
    part = hashlib.sha256(json.dumps(content, sort_keys=True).encode() + files.digest())
    return full.hexdigest(), part.hexdigest()


def _room_bounds(cfg: SceneConfig, meshes) -> np.ndarray | None:
    """(2, 3) world bounds of the room objects at frame 0 (the default parallax proxy)."""
    boxes = [mesh.transformed(transform_at(obj, 0)).corners.reshape(-1, 3)
             for obj, mesh in zip(cfg.objects, meshes, strict=True) if obj.shape == "room"]
    if not boxes:
        return None
    points = np.concatenate(boxes)
    return np.array([points.min(axis=0), points.max(axis=0)])


def build_scene(cfg: SceneConfig, source: str, prov: dict | None = None) -> Scene:
    """Build the scene; raises Problems naming the file and field for what cannot be built.
    `prov`: load_config's provenance, naming the file a field came from (an include,
    `--set`) in every message (else `source`)."""
    from ..config.load import origin

    def where(loc: tuple) -> str:
        return origin(prov, loc, source) if prov else source

    problems: list[Problem] = []
    material_index = {name: k for k, name in enumerate(cfg.materials)}
    meshes: list[Mesh | None] = []
    for i, obj in enumerate(cfg.objects):
        try:
            meshes.append(object_mesh(obj, source))
        except (OSError, ValueError) as e:
            field = "path" if obj.shape == "mesh" else "shape"
            problems.append(Problem(where(("objects", i, field)), f"objects.{i}.{field}",
                                    str(e).splitlines()[0]))
            meshes.append(None)
    mirror_parts: list[Triangles] = []
    mirror_pieces: list[Pieces] = []
    exact: list[np.ndarray] = []
    n_obj = len(cfg.objects)
    for j, m in enumerate(cfg.mirrors):
        try:
            mesh, is_exact = mirror_mesh(m, source)
        except (OSError, ValueError) as e:
            field = "profile" if m.shape == "extrusion" else "path"
            problems.append(Problem(where(("mirrors", j, field)), f"mirrors.{j}.{field}",
                                    str(e).splitlines()[0]))
            continue
        if (far := too_far("mirrors", j, m, reach(mesh.corners), where)) is not None:
            problems.append(far)
            continue
        kept = mesh.without_degenerate()
        mirror_parts.append(_triangles(kept, -1, n_obj + j))
        mirror_pieces.append(Pieces.of(kept, mirror_parts[-1]))
        exact.append(np.full(mirror_parts[-1].count, is_exact))
    try:
        materials = _materials(cfg, source)
    except TextureError as e:
        problems.append(Problem(source, f"materials.{e.material}.path", e.message))
    if problems:
        raise Problems(problems)
    from .fit import warn_textured_without_uvs

    warn_textured_without_uvs(cfg, meshes)
    mirror_tris = _concat(mirror_parts)
    mirror_exact = np.concatenate(exact) if exact else np.zeros(0, bool)
    static_parts: dict[int, tuple[Triangles, Pieces]] = {}
    moving = [i for i, o in enumerate(cfg.objects) if o.motion]

    def placed(i: int, frame_index: int) -> tuple[Triangles, Pieces]:
        """Object i's world triangles at a frame, and their closed pieces with world boxes."""
        obj = cfg.objects[i]
        world = meshes[i].transformed(transform_at(obj, frame_index)).without_degenerate()
        tris = _triangles(world, material_index[obj.material], i)
        return tris, Pieces.of(world, tris)

    for i, obj in enumerate(cfg.objects):
        if not obj.motion:
            static_parts[i] = placed(i, 0)
        found = (motion_reach(meshes[i], obj.motion) if obj.motion
                 else reach(static_parts[i][0].corners))
        if (far := too_far("objects", i, obj, found, where)) is not None:
            problems.append(far)
    if problems:
        raise Problems(problems)
    last: dict = {}

    def geometry_at(frame_index: int) -> Geometry:
        mats = tuple(transform_at(cfg.objects[i], frame_index).tobytes() for i in moving)
        if last.get("key") == mats:
            return last["geometry"]
        parts = [static_parts[i] if i in static_parts else placed(i, frame_index)
                 for i in range(n_obj)]
        closed_piece, closed_boxes = _joined_pieces([p for _, p in parts] + mirror_pieces)
        geometry = Geometry(_concat([t for t, _ in parts]), mirror_tris, mirror_exact,
                            ("geometry", mats), closed_boxes, closed_piece)
        last.update(key=mats, geometry=geometry)
        return geometry

    hashes = scene_hashes(cfg, source)
    return Scene(
        name=cfg.scene.name,
        source=source,
        shading=LAMBERT if cfg.scene.shading == "lambert" else UNLIT,
        background=np.array(cfg.scene.background, np.float32),
        ambient=float(cfg.scene.ambient),
        materials=materials,
        lights=_lights(cfg),
        mirrors=_mirrors(cfg),
        surface_names=[o.name for o in cfg.objects] + [m.name for m in cfg.mirrors],
        n_objects=n_obj,
        frame_count=cfg.camera.frame_count,
        scene_hash=hashes[0],
        content_hash=hashes[1],
        room_bounds=_room_bounds(cfg, meshes),
        geometry_at=geometry_at,
        mirror_profiles={j: extrusion_profile(m) for j, m in enumerate(cfg.mirrors)
                         if isinstance(m, ExtrusionMirror)},
    )
