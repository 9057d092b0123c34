"""Estimate what a render will need before allocating it: triangles from the tessellation
parameters (no mesh is built) and bytes from the image, the triangles and the technique's
maps. Past the documented triangle limit, or past the memory this machine has, one line
says how much is needed instead of an out-of-memory kill minutes later."""

from __future__ import annotations

import os

from .limits import MAX_TRIANGLES

# bytes per unit, generous (kernels keep several float buffers per pixel and per triangle)
BYTES_PER_PIXEL = 256
BYTES_PER_TRIANGLE = 600
# dprm zexel maps: color, depth, triangle ids, mips (48), the warp's colour + triangle rows
# (16), and while capturing, the rasterizer's sort-last buffers (8 per thread); envmap faces
BYTES_PER_TEXEL = 48 + 16 + 8 * max(os.cpu_count() or 1, 2)
MESH_FILE_BYTES_PER_TRIANGLE = 12  # a binary STL triangle is 50 bytes; be generous
# distmap, per texel of each layer of each face: kept per mirror, its colour (12), depth (4),
# surface id (4), and 1 / depth and the ids again as the search reads them (8:
# maps/distance_search.search_texels); while one map is stored in or read from the cache,
# its EXR parts stacked and its ids as floats besides (measured 31 at 512 texels, 8 layers)
DISTMAP_BYTES_KEPT = 28
DISTMAP_BYTES_STORING = 32


def triangles(item, source: str) -> int:
    """An upper estimate of the triangles one object or mirror tessellates into."""
    shape = item.shape
    if shape == "quad":
        return 2
    if shape in ("box", "room", "pyramid", "rectangle"):
        return 12
    if shape == "sphere":
        if getattr(item, "tessellation", "uv") == "ico":
            return 20 * 4 ** item.subdivisions
        return 2 * item.segments * max(item.segments // 2, 1)
    if shape in ("cylinder", "cone"):
        return 4 * item.segments
    if shape == "torus":
        return 2 * item.major_segments * item.minor_segments
    if shape == "teapot":
        return 64 * item.subdivisions**2
    if shape == "clutter":  # its count lands within 0.01% of `triangles` (1,600 at least)
        return max(item.triangles, 2_000) * 101 // 100
    if shape == "extrusion":
        return 2 * max(len(item.profile) - 1, 1) * item.subdivisions
    if shape == "cap":
        return 2 * item.segments * item.segments
    if shape == "mesh":
        path = os.path.join(os.path.dirname(os.path.abspath(source)), item.path)
        try:
            return os.path.getsize(path) // MESH_FILE_BYTES_PER_TRIANGLE
        except (OSError, ValueError):
            return 0
    return 0


def _map_bytes(technique, mirrors: int) -> int:
    layers = getattr(technique, "layers", None)
    if isinstance(layers, int):  # distmap: layered cube maps, each face captured in turn
        texels = layers * 6 * technique.resolution**2
        return (texels * (DISTMAP_BYTES_KEPT * mirrors + DISTMAP_BYTES_STORING)
                + BYTES_PER_TEXEL * technique.resolution**2)
    maps = getattr(technique, "maps", None)
    if maps is not None and hasattr(maps, "resolution"):  # dprm: count maps per mirror
        return BYTES_PER_TEXEL * maps.resolution**2 * getattr(maps, "count", 1) * mirrors
    resolution = getattr(technique, "resolution", None)
    if isinstance(resolution, int):  # envmap: six faces per mirror
        return BYTES_PER_TEXEL * 6 * resolution**2 * mirrors
    return 0


def estimate(cfg, source: str) -> tuple[int, dict[tuple, int]]:
    """(triangles, bytes by the field that asks for them) a render of `cfg` needs, roughly."""
    tris = sum(triangles(o, source) for o in cfg.objects)
    tris += sum(triangles(m, source) for m in cfg.mirrors)
    samples = getattr(cfg.technique, "samples", 1) or 1
    if not isinstance(samples, int):
        samples = 1
    pixels = cfg.camera.width * cfg.camera.height * samples * samples
    parts = {("camera", "width"): pixels * BYTES_PER_PIXEL,
             ("objects",): tris * BYTES_PER_TRIANGLE,
             ("technique",): _map_bytes(cfg.technique, len(cfg.mirrors))}
    return tris, parts


def available_bytes() -> int | None:
    """Memory this process may use: MemAvailable, or the cgroup limit if lower."""
    best = None
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    best = int(line.split()[1]) * 1024
    except (OSError, ValueError):
        pass
    for path in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            with open(path) as f:
                text = f.read().strip()
            if text.isdigit():
                best = min(best, int(text)) if best else int(text)
        except OSError:
            pass
    return best


def _size(n: int) -> str:
    return f"{n / (1 << 30):.1f} GiB" if n >= 1 << 30 else f"{n / (1 << 20):.0f} MiB"


def memory_problem(cfg, source: str) -> tuple[tuple, str] | None:
    """(field, message) when the scene is past the triangle limit or this machine's memory."""
    tris, parts = estimate(cfg, source)
    need = sum(parts.values())
    if tris > MAX_TRIANGLES:
        return ("objects",), (f"about {tris:,} triangles; the limit is {MAX_TRIANGLES:,} "
                              "(lower segments, subdivisions or triangles)")
    have = available_bytes()
    if have is not None and need > have:
        return max(parts, key=parts.get), (f"this render needs about {_size(need)} of memory; "
                             f"{_size(have)} is available")
    return None
