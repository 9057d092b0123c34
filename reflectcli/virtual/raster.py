"""Drawing virtual objects: the virtual triangles rasterized over a reflector's pixels,
with geometry in front of the reflector removed, and shaded from their original surfaces."""

from __future__ import annotations

import numpy as np

from ..camera import Camera
from ..geometry import transform_plane
from ..raster.primary import Primary
from ..raster.rasterize import FLAG_MIRROR, FLAG_SKIP, RasterWorkspace, rasterize, standard_planes
from ..raster.shade import shade_buffers
from ..scene.types import Scene, Triangles
from .refine import reflector_grid


def draw_virtual(scene: Scene, primary: Primary, camera: Camera, clip_from_world: np.ndarray,
                 reflected: Triangles, virtual: np.ndarray, dropped: np.ndarray,
                 stencil: np.ndarray, sid: int, mirror_plane: np.ndarray | None,
                 reflector_test: str, incoming: np.ndarray,
                 workspace: RasterWorkspace | None = None) -> np.ndarray:
    """(H, W, 3) colors of the virtual triangles `virtual` (T, 3, 3 world) over `stencil`
    (H, W screen); `dropped` (T,) are skipped. A planar mirror (`mirror_plane` n, d facing
    the eye) clips them exactly; a curved one applies `reflector_test`.

    Each fragment is shaded as the ray tracer shades the same hit: seen along the reflected
    ray that reaches it, `incoming` (H, W, 3 world: per pixel, the eye ray reflected at the
    reflector point under it; `reflected_rays`), not from the real eye, which sees the
    original surface from its other side wherever the mirror shows its underside.

    Only the stencil's pixels of the result are meaningful (the others hold whatever the
    last call left). `workspace` (outputs=True): the rasterizer's buffers and the colors
    kept from call to call; the result is valid until the next call with it."""
    ws = workspace if workspace is not None else RasterWorkspace(outputs=True)
    h, w = stencil.shape
    planes = standard_planes()  # clip space
    floor = None
    if mirror_plane is not None:  # the exact case: the mirror plane clips
        planes = np.vstack([planes, mirror_clip_plane(mirror_plane, camera.eye,
                                                      clip_from_world)])
    elif reflector_test == "zbuffer":
        floor = ws.get("virtual_floor", (h, w), np.float32)
        floor.fill(0.0)
        np.copyto(floor, primary.buffers.depth, where=stencil)
    elif reflector_test == "clip_planes":
        pts = primary.triangles.corners[primary.triangles.surface == sid].reshape(-1, 3)
        planes = np.vstack([planes, box_planes(pts, camera.eye, clip_from_world)])
    flags = np.where(reflected.surface >= scene.n_objects, FLAG_MIRROR, 0).astype(np.uint8)
    flags[dropped] |= FLAG_SKIP
    buffers = rasterize(np.ascontiguousarray(virtual, np.float32), flags, clip_from_world,
                        camera.width, camera.height, planes, mask=stencil, depth_floor=floor,
                        workspace=ws)
    # shaded where the stencil is: fragments (and the pixels fill_cracks reads) lie there
    colors, _ = shade_buffers(buffers, reflected, scene, camera.eye, incoming, stencil=stencil,
                              out=(ws.get("virtual_rgb", (h, w, 3), np.float32),
                                   ws.get("virtual_surface", (h, w), np.int32)))
    if mirror_plane is None:
        fill_cracks(colors, buffers.triangle >= 0, stencil)
    return colors


def fill_cracks(colors: np.ndarray, covered: np.ndarray, stencil: np.ndarray) -> None:
    """Close one-pixel cracks between virtual triangles, in place: a stencil pixel no
    fragment covered whose two neighbours across it (left and right, or above and below)
    are covered takes their mean color.

    Curved reflectors only. Reflected triangles are split n x n with n chosen per triangle
    (by its longest edge), so two neighbours split differently meet in a T-junction; the
    finer side's extra virtual vertices bend off the coarser side's straight virtual edge,
    and pixel centers fall through the sliver between them (cylinder: 21 background pixels
    along the reflected wall/floor seam). A reflection one pixel wide between covered pixels
    on both sides is not something the tessellated objects can show, so the fill is safe;
    wider gaps (a reflection of the background) are kept."""
    h, w = covered.shape
    ys, xs = np.nonzero(stencil & ~covered)
    if not ys.size:
        return
    # per crack pixel (in row-major order), the same sums in the same order as over whole
    # images: above + below, then left + right
    total = np.zeros((ys.size, 3), np.float64)
    count = np.zeros(ys.size, np.int64)
    for dy, dx in ((1, 0), (0, 1)):
        pair = (ys >= dy) & (xs >= dx) & (ys + dy < h) & (xs + dx < w)
        k = np.flatnonzero(pair)
        k = k[covered[ys[k] - dy, xs[k] - dx] & covered[ys[k] + dy, xs[k] + dx]]
        if not k.size:
            continue
        total[k] += colors[ys[k] - dy, xs[k] - dx].astype(np.float64)
        total[k] += colors[ys[k] + dy, xs[k] + dx].astype(np.float64)
        count[k] += 2
    filled = count > 0
    colors[ys[filled], xs[filled]] = (total[filled] / count[filled][:, None]).astype(np.float32)


def reflected_rays(primary: Primary, eye: np.ndarray,
                   workspace: RasterWorkspace | None = None) -> np.ndarray:
    """(H, W, 3) world: per mirror pixel of the primary pass, the direction of the eye ray
    reflected at the surface point under it (interpolated normal; NaN elsewhere: only mirror
    pixels are drawn over). For a planar mirror every such ray leaves the mirrored eye; for a
    curved one each pixel has its own viewpoint. `workspace`: arrays kept across frames (the
    result is valid until the next call with it)."""
    ws = workspace if workspace is not None else RasterWorkspace()
    tri = primary.buffers.triangle
    h, w = tri.shape
    mirrors = ws.get("incoming_triangle", (h, w), np.int32)
    np.copyto(mirrors, tri)
    mirrors[~primary.frame.mirror_mask] = -1
    _, r = reflector_grid(mirrors, primary.buffers.b1, primary.buffers.b2,
                          primary.triangles.corners, primary.triangles.normals, eye,
                          out=(None, ws.get("incoming_r", (h, w, 3), np.float64)))
    return r


def mirror_clip_plane(plane: np.ndarray, eye: np.ndarray,
                      clip_from_world: np.ndarray) -> np.ndarray:
    """Clip-space plane keeping what lies behind a planar mirror (n, d; world, n . eye + d
    >= 0), moved a little behind it so the mirror's own wall is not reflected."""
    n, d = plane[:3], float(plane[3])
    offset = 1e-4 * (1.0 + abs(d) + float(np.abs(eye).max()))
    clip = transform_plane(np.append(-n, -d - offset), clip_from_world)
    return clip / np.abs(clip).max()


def box_planes(points: np.ndarray, eye: np.ndarray, clip_from_world: np.ndarray) -> np.ndarray:
    """Clip-space planes keeping what lies behind the reflector's bounding-box faces that
    face the eye (at most three of the six); `points` (N, 3) world."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    planes = []
    for axis in range(3):
        for sign, bound in ((1.0, hi[axis]), (-1.0, lo[axis])):
            if sign * (eye[axis] - bound) > 0:  # this face looks at the eye
                plane = np.zeros(4)  # world
                plane[axis] = -sign
                plane[3] = sign * bound
                clip = transform_plane(plane, clip_from_world)
                planes.append(clip / np.abs(clip).max())
    return np.array(planes).reshape(-1, 4)
