"""Config -> Scene: primitives and mesh files flattened to world-space float32 arrays."""

from __future__ import annotations

import hashlib
import json

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
from .mesh import Mesh
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


def closed_outward(obj) -> bool:
    """Whether the object's mesh is closed with every face turned outward (from an eye
    outside it, a ray meets a front face first, so its back faces can be culled): the
    solids reflect makes (tests/scene/test_closed.py holds each to that). Meshes read from
    files, the teapot (open at its spout) and clutter are not assumed closed."""
    s = obj.shape
    if s == "box":
        return all(a < b for a, b in zip(obj.min, obj.max, strict=True))
    if s == "cylinder":
        return bool(obj.caps)
    if s == "torus":  # a spindle torus folds through itself
        return obj.minor_radius < obj.major_radius
    return s in ("sphere", "cone", "pyramid")


def _whole(world: Mesh, kept: int) -> bool:
    """Whether `without_degenerate`, which kept `kept` of `world`'s triangles, kept every
    one with an area at all (a pole's zero-area triangles go, and close nothing): a solid
    so small that it loses real triangles is open, its back faces seen through the holes."""
    return int(np.count_nonzero(world.areas() > 0)) == kept


def _box_of(corners: np.ndarray) -> np.ndarray:
    """(6,) float64 min then max of (T, 3, 3) corners; NaN for none."""
    if corners.shape[0] == 0:
        return np.full(6, np.nan)
    points = corners.reshape(-1, 3).astype(np.float64)
    return np.concatenate([points.min(axis=0), points.max(axis=0)])


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


def build_scene(cfg: SceneConfig, source: str) -> Scene:
    """Build the scene; raises Problems naming the file and field for what cannot be built."""
    problems: list[Problem] = []
    material_index = {name: k for k, name in enumerate(cfg.materials)}
    meshes: list[Mesh | None] = []
    for i, obj in enumerate(cfg.objects):
        try:
            meshes.append(object_mesh(obj, source))
        except (OSError, ValueError) as e:
            field = "path" if obj.shape == "mesh" else "shape"
            problems.append(Problem(source, f"objects.{i}.{field}", str(e).splitlines()[0]))
            meshes.append(None)
    mirror_parts: list[Triangles] = []
    mirror_meshes: dict[int, tuple[Mesh, int]] = {}  # each mirror's, and its kept count
    exact: list[np.ndarray] = []
    n_obj = len(cfg.objects)
    for j, m in enumerate(cfg.mirrors):
        try:
            mesh, is_exact = mirror_mesh(m, source)
        except (OSError, ValueError) as e:
            field = "profile" if m.shape == "extrusion" else "path"
            problems.append(Problem(source, f"mirrors.{j}.{field}", str(e).splitlines()[0]))
            continue
        mirror_parts.append(_triangles(mesh.without_degenerate(), -1, n_obj + j))
        mirror_meshes[j] = (mesh, mirror_parts[-1].count)
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
    static_parts: dict[int, Triangles] = {}
    moving = [i for i, o in enumerate(cfg.objects) if o.motion]
    # closed surfaces' world boxes (NaN: open): the static ones once, the moving ones per
    # frame
    closed = [closed_outward(obj) for obj in cfg.objects]
    static_boxes = np.full((n_obj + len(cfg.mirrors), 6), np.nan)
    for i, (obj, mesh) in enumerate(zip(cfg.objects, meshes, strict=True)):
        if not obj.motion:
            world = mesh.transformed(transform_at(obj, 0))
            static_parts[i] = _triangles(world.without_degenerate(),
                                         material_index[obj.material], i)
            if closed[i] and _whole(world, static_parts[i].count):
                static_boxes[i] = _box_of(static_parts[i].corners)
    for j, m in enumerate(cfg.mirrors):
        if m.shape == "sphere" and _whole(*mirror_meshes[j]):
            static_boxes[n_obj + j] = _box_of(
                mirror_tris.corners[mirror_tris.surface == n_obj + j])
    last: dict = {}

    def geometry_at(frame_index: int) -> Geometry:
        mats = tuple(transform_at(cfg.objects[i], frame_index).tobytes() for i in moving)
        if last.get("key") == mats:
            return last["geometry"]
        parts = []
        boxes = static_boxes.copy() if moving else static_boxes
        for i, (obj, mesh) in enumerate(zip(cfg.objects, meshes, strict=True)):
            if i in static_parts:
                parts.append(static_parts[i])
            else:
                world = mesh.transformed(transform_at(obj, frame_index))
                parts.append(_triangles(world.without_degenerate(),
                                        material_index[obj.material], i))
                if closed[i] and _whole(world, parts[-1].count):
                    boxes[i] = _box_of(parts[-1].corners)
        geometry = Geometry(_concat(parts), mirror_tris, mirror_exact, ("geometry", mats),
                            boxes)
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
