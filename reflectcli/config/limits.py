"""Documented size limits: every size a scene can ask for is bounded, so no input can make a
render run for hours before its first frame or allocate more memory than a machine has.

| what                                   | limit                 |
|---|---|
| scene / section / include file (TOML)  | 4 MiB                 |
| mesh file, with the glTF buffers, OBJ materials, textures it names | 512 MiB |
| texture file                           | 256 MiB               |
| texture dimensions                     | 16384 x 16384 texels, 64 Mtexels |
| texture channels (file header)         | 64; 256M texels x channels, tiles too |
| frame `--resume` keeps (header)        | the camera's size, R G B of <= 16 channels |
| image file `compare` reads             | 4 GiB; the image size limits (tiles too), 64 channels |
| include chain                          | 16 files deep         |
| nesting of tables / arrays in a file   | 24 levels             |
| image width, height                    | 16384 pixels each, 64 Mpixels |
| camera path frames                     | 100,000               |
| tessellation segments (any)            | 4096                  |
| sphere `subdivisions` (ico)            | 7                     |
| teapot `subdivisions`                  | 64                    |
| extrusion `subdivisions`               | 4096                  |
| triangles in a scene (built)           | 20,000,000            |
| virtual: tessellated reflected objects | 1,000,000 (splits scaled down, with a notice) |
| coordinates (any position, size)       | magnitude <= 1e6, also in world space |
| mesh file coordinates                  | finite, magnitude <= 1e9 in the file |
| mesh texture coordinates, texels (linear) | finite, magnitude <= 1e9 |
| camera `near`                          | >= 1e-6, far / near <= 1e9 |
| camera `fov_y`                         | >= 0.01, <= 170 degrees |
| lights                                 | 256                   |
| output names (`scene.name`, `output.log`, each folder of the output root) | 255 bytes |
| output paths (root/name/technique/file; root: `--out` or `output.dir`) | 4095 bytes |
| any other number (colors, intensities) | magnitude <= 1e9      |

These are checked before anything is allocated (`check_config`); the memory a render will
need is estimated from them before it starts (`reflectcli/config/memory.py`). The coordinate
limit also holds for the geometry as built, in world space (after a mesh's `fit` and the
transform, at every keyframe: scene/extent.py), before anything is written. A mesh file's own
coordinates past 1e9 would overflow trimesh's vertex merge (int64 at its 1e-8 tolerance),
which then joins vertices that are apart.
"""

from __future__ import annotations

import math

from .names import output_path_lengths

MAX_TOML_BYTES = 4 << 20
MAX_MESH_BYTES = 512 << 20
MAX_TEXTURE_BYTES = 256 << 20
MAX_TEXTURE_SIDE = 16384
MAX_TEXTURE_TEXELS = 64 << 20
# what a texture file's header may claim (the texels read are then at most 1 GiB as float:
# a 1 MB TIFF claiming 1024 x 1024 texels of 1000 channels was a MemoryError)
MAX_TEXTURE_CHANNELS = 64
MAX_TEXTURE_VALUES = MAX_TEXTURE_TEXELS * 4  # texels x channels, in the image and in a tile
MAX_INCLUDE_DEPTH = 16
MAX_NESTING = 24
MAX_IMAGE_SIDE = 16384
MAX_IMAGE_PIXELS = 64 << 20
MAX_IMAGE_FILE_BYTES = 4 << 30  # `compare`'s inputs: a frame at the image limits fits
MAX_IMAGE_CHANNELS = 64  # `compare`'s inputs (a frame has at most a dozen)
MAX_FRAMES = 100_000
MAX_SEGMENTS = 4096
MAX_TEAPOT_SUBDIVISIONS = 64
MAX_TRIANGLES = 20_000_000
MAX_TESSELLATED_TRIANGLES = 1_000_000  # virtual: reflected objects split for a reflector
MAX_COORDINATE = 1e6
MIN_NEAR = 1e-6
MAX_DEPTH_RATIO = 1e9
MIN_FOV_Y = 0.01
MAX_FOV_Y = 170.0  # wider, the image is a speck in the middle (179.99 showed background)
MAX_LIGHTS = 256  # every lit pixel sums every light: 90,000 took 5 s for 160x120 pixels
MIN_SCALE = 1e-6
MAX_NUMBER = 1e9  # any number in a scene (colors, intensities, parameters)


def check_config(cfg, add) -> None:
    """Call add(loc, message) for every value past a documented limit or too degenerate to
    render (a zero scale, a zero light direction, a repeated quad corner)."""
    output_names(cfg, add)
    output_path_lengths(cfg, add)
    if _huge_numbers(cfg.model_dump(mode="python"), (), add):
        return  # one line per huge number is enough; the checks below assume sane ones
    capture = getattr(cfg.technique, "capture", None)  # envmap: points by mirror name
    if isinstance(capture, dict):
        names = {m.name for m in cfg.mirrors}
        for name, point in capture.items():
            if name not in names:
                add(("technique", "capture", name), "no mirror of that name")
            else:
                _points(add, ("technique", "capture", name), [point])
    _proxy_box(add, cfg.technique)
    cam = cfg.camera
    too_wide = [key for key in ("width", "height") if getattr(cam, key) > MAX_IMAGE_SIDE]
    for key in too_wide:
        add(("camera", key), f"must be <= {MAX_IMAGE_SIDE}")
    if not too_wide and cam.width * cam.height > MAX_IMAGE_PIXELS:  # one line per mistake
        add(("camera", "width"), f"width x height must be <= {MAX_IMAGE_PIXELS} pixels",
            (("camera", "height"),))
    if cam.near < MIN_NEAR:
        add(("camera", "near"), f"must be >= {MIN_NEAR:g}")
    elif cam.far / cam.near > MAX_DEPTH_RATIO:
        add(("camera", "far"), f"far / near must be <= {MAX_DEPTH_RATIO:g}",
            (("camera", "near"),))
    _fov(add, ("camera", "fov_y"), cam.fov_y)
    _points(add, ("camera", "eye"), [cam.eye])
    _points(add, ("camera", "target"), [cam.target])
    _direction(add, ("camera", "up"), cam.up)
    if cam.path is not None:
        if cam.path.frames > MAX_FRAMES:
            add(("camera", "path", "frames"), f"must be <= {MAX_FRAMES}")
        for k, key in enumerate(cam.path.keys):
            _points(add, ("camera", "path", "keys", k, "eye"), [key.eye])
            _points(add, ("camera", "path", "keys", k, "target"), [key.target])
            if key.up is not None:
                _direction(add, ("camera", "path", "keys", k, "up"), key.up)
            if key.fov_y is not None:
                _fov(add, ("camera", "path", "keys", k, "fov_y"), key.fov_y)
    if len(cfg.lights) > MAX_LIGHTS:
        add(("lights",), f"{len(cfg.lights):,} lights; the limit is {MAX_LIGHTS}")
    for i, light in enumerate(cfg.lights[:MAX_LIGHTS]):
        if light.kind == "directional":
            _direction(add, ("lights", i, "direction"), light.direction)
        else:
            _points(add, ("lights", i, "position"), [light.position])
    for section, items in (("objects", cfg.objects), ("mirrors", cfg.mirrors)):
        for i, item in enumerate(items):
            _item(add, (section, i), item)


def _huge_numbers(node, loc: tuple, add) -> bool:
    """Every number anywhere in the scene within +-MAX_NUMBER (colors, intensities,
    parameters: 1e308 overflows to infinity in the kernels); True if one is not."""
    found = False
    stack = [(node, loc)]
    while stack:
        value, where = stack.pop()
        if isinstance(value, dict):
            stack.extend((v, (*where, k)) for k, v in value.items())
        elif isinstance(value, (list, tuple)):
            flat = [x for v in value for x in (v if isinstance(v, (list, tuple)) else [v])]
            numbers = [v for v in flat if isinstance(v, (int, float))
                       and not isinstance(v, bool)]
            if numbers and len(numbers) == len(flat):  # a vector, or a list of vectors
                if any(abs(v) > MAX_NUMBER for v in numbers):
                    add(where, f"numbers must be within +-{MAX_NUMBER:g}")
                    found = True
            else:
                stack.extend((v, (*where, i)) for i, v in enumerate(value))
        elif (isinstance(value, (int, float)) and not isinstance(value, bool)
              and abs(value) > MAX_NUMBER and where[-1:] != ("seed",)):
            add(where, f"must be within +-{MAX_NUMBER:g}")
            found = True
    return found


def output_names(cfg, add) -> None:
    """Outputs stay inside the output folder and never replace one another: the scene name is
    a folder name, the log a plain file name that is no other output's (a frame's, the
    timings summary's, the lock's: output/names.py)."""
    from ..output.names import taken_by

    if cfg.scene.name in (".", ".."):
        add(("scene", "name"), "must name a folder ('.' and '..' are not names)")
    log = cfg.output.log
    if (not log or "/" in log or "\\" in log or "\0" in log or log in (".", "..")
            or log.startswith(".")):
        add(("output", "log"), "must be a plain file name inside the frame folder")
    elif (taken := taken_by(log)) is not None:
        add(("output", "log"), f"must not be named like {taken}")
    if "\0" in cfg.output.dir:
        add(("output", "dir"), "path contains a NUL byte")


def _fov(add, loc, fov_y: float) -> None:
    if fov_y < MIN_FOV_Y:
        add(loc, f"must be >= {MIN_FOV_Y}")
    elif fov_y > MAX_FOV_Y:
        add(loc, f"must be <= {MAX_FOV_Y:g} degrees")


def _proxy_box(add, technique) -> None:
    """envmap's parallax box: both corners or neither (one alone was silently ignored),
    and min below max on every axis (an inside-out box was accepted)."""
    lo, hi = getattr(technique, "proxy_min", None), getattr(technique, "proxy_max", None)
    if (lo is None) != (hi is None):
        missing = "proxy_max" if hi is None else "proxy_min"
        add(("technique", missing), "required with the other corner of the proxy box")
    elif lo is not None and any(a > b for a, b in zip(lo, hi, strict=True)):
        add(("technique", "proxy_min"), "must be <= proxy_max on every axis",
            (("technique", "proxy_max"),))


def _finite_small(values) -> bool:
    return all(math.isfinite(v) and abs(v) <= MAX_COORDINATE for v in values)


def _points(add, loc, points) -> None:
    for p in points:
        if not _finite_small(p):
            add(loc, f"coordinates must be within +-{MAX_COORDINATE:g}")
            return


def _direction(add, loc, v) -> None:
    if not _finite_small(v):
        add(loc, f"coordinates must be within +-{MAX_COORDINATE:g}")
    elif math.sqrt(sum(c * c for c in v)) < 1e-9:
        add(loc, "must not be zero")


def _transform(add, loc, t) -> None:
    _points(add, (*loc, "translate"), [t.translate])
    scale = t.scale if isinstance(t.scale, tuple) else (t.scale,)
    if not _finite_small(scale):
        add((*loc, "scale"), f"must be within +-{MAX_COORDINATE:g}")
    elif any(abs(s) < MIN_SCALE for s in scale):
        add((*loc, "scale"), f"must not be zero (magnitude >= {MIN_SCALE:g})")


def _item(add, loc, item) -> None:
    for key in ("segments", "major_segments", "minor_segments"):
        value = getattr(item, key, None)
        if isinstance(value, int) and value > MAX_SEGMENTS:
            add((*loc, key), f"must be <= {MAX_SEGMENTS}")
    shape = item.shape
    subdivisions = getattr(item, "subdivisions", None)
    if shape == "teapot" and subdivisions > MAX_TEAPOT_SUBDIVISIONS:
        add((*loc, "subdivisions"), f"must be <= {MAX_TEAPOT_SUBDIVISIONS}")
    if shape == "extrusion" and subdivisions > MAX_SEGMENTS:
        add((*loc, "subdivisions"), f"must be <= {MAX_SEGMENTS}")
    for key in ("transform",):
        t = getattr(item, key, None)
        if t is not None:
            _transform(add, (*loc, key), t)
    for k, key in enumerate(getattr(item, "motion", None) or []):
        _transform(add, (*loc, "motion", k), key)
    for key in ("center", "origin", "min", "max"):
        value = getattr(item, key, None)
        if value is not None:
            _points(add, (*loc, key), [value])
    for key in ("normal", "axis"):
        value = getattr(item, key, None)
        if value is not None and not _finite_small(value):
            add((*loc, key), f"coordinates must be within +-{MAX_COORDINATE:g}")
    for key in ("radius", "height", "size", "major_radius", "minor_radius"):
        value = getattr(item, key, None)
        values = value if isinstance(value, tuple) else (value,)
        if value is not None and not _finite_small(values):
            add((*loc, key), f"must be <= {MAX_COORDINATE:g}")
    if getattr(item, "profile", None) is not None:
        _points(add, (*loc, "profile"), [tuple(p) for p in item.profile])
    corners = getattr(item, "corners", None)
    if corners is not None:
        if not all(_finite_small(c) for c in corners):
            add((*loc, "corners"), f"coordinates must be within +-{MAX_COORDINATE:g}")
        elif len(set(corners)) < len(corners) and hasattr(item, "material"):
            # objects only: a mirror with a repeated corner is reported as "zero area"
            add((*loc, "corners"), "a corner is repeated")


def limit_problems(cfg, prov: dict, display: str, source: str | None = None,
                   memory=None) -> list:
    """check_config's findings as Problems naming the file each value came from; then, if
    none, `memory(cfg, source)` (config/memory.py's estimate, passed in by the loader so that
    this module does not import the one that imports it)."""
    from ..errors import Problem

    problems: list = []

    def add(loc: tuple, message: str, related: tuple = ()) -> None:
        """`related`: the other fields a check across fields reads; one that `--set` gave
        blames it (the file's value at `loc` is not what made the pair wrong)."""
        file = origin(prov, loc, display)
        if any(origin(prov, other, display) == "--set" for other in related):
            file = "--set"
        problems.append(Problem(file, ".".join(str(p) for p in loc), message))

    check_config(cfg, add)
    if not problems and source is not None and memory is not None:
        found = memory(cfg, source)
        if found is not None:
            add(*found)
    return problems


def origin(prov: dict, loc: tuple, default: str) -> str:
    """Where the value at `loc` came from. A table's own error (a check across its fields)
    is blamed on `--set` when an override changed anything in it: the table as a whole may
    come from the file or `--technique`, but the override is what made it wrong (so an
    array's `camera.eye.0=1e7` is blamed on --set, not on the file that holds camera.eye)."""
    if any(source == "--set" and len(k) > len(loc) and k[: len(loc)] == loc
           for k, source in prov.items()):
        return "--set"
    for n in range(len(loc), -1, -1):
        if loc[:n] in prov:
            return prov[loc[:n]]
    return default
