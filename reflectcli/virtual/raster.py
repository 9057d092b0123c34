"""Drawing virtual objects: the virtual triangles rasterized over a reflector's pixels,
with geometry in front of the reflector removed, and shaded from their original surfaces."""

from __future__ import annotations

import numpy as np

from ..camera import Camera
from ..geometry import transform_plane
from ..raster.primary import Primary
from ..raster.rasterize import RasterWorkspace, rasterize, standard_planes
from ..raster.shade import shade_buffers
from ..scene.types import Scene, Triangles
from .compose import fill_cracks
from .refine import mirror_rays


def draw_virtual(scene: Scene, primary: Primary, camera: Camera, clip_from_world: np.ndarray,
                 reflected: Triangles, virtual: np.ndarray, flags: np.ndarray,
                 stencil: np.ndarray, box: tuple[int, int, int, int], sid: int,
                 mirror_plane: np.ndarray | None, reflector_test: str,
                 incoming: np.ndarray | None,
                 workspace: RasterWorkspace | None = None) -> np.ndarray:
    """(H, W, 3) colors of the virtual triangles `virtual` (T, 3, 3 world, float32) over
    `stencil` (H, W screen) inside `box` (rows y0..y1-1, columns x0..x1-1); `flags` (T,):
    the rasterizer's (gather_corners: mirrors marked, dropped ones skipped). A planar
    mirror (`mirror_plane` n, d facing the eye) clips them exactly; a curved one applies
    `reflector_test`.

    Each fragment is shaded as the ray tracer shades the same hit: seen along the reflected
    ray that reaches it, `incoming` (H, W, 3 world: per pixel, the eye ray reflected at the
    reflector point under it; `reflected_rays`), not from the real eye, which sees the
    original surface from its other side wherever the mirror shows its underside. None:
    shaded from the real eye (only right for unlit shading, which reads no direction).

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
        # read only under the stencil: set within its box alone
        floor = ws.get("virtual_floor", (h, w), np.float32)
        rows, cols = slice(box[0], box[1]), slice(box[2], box[3])
        floor[rows, cols] = 0.0
        np.copyto(floor[rows, cols], primary.buffers.depth[rows, cols],
                  where=stencil[rows, cols])
    elif reflector_test == "clip_planes":
        pts = primary.triangles.corners[primary.triangles.surface == sid].reshape(-1, 3)
        planes = np.vstack([planes, box_planes(pts, camera.eye, clip_from_world)])
    # the stencil as the uint8 the rasterizer takes, a view: not a copy of the image a pass
    mask = stencil.view(np.uint8) if stencil.dtype == np.bool_ else stencil
    buffers = rasterize(np.ascontiguousarray(virtual, np.float32), flags, clip_from_world,
                        camera.width, camera.height, planes, mask=mask, depth_floor=floor,
                        workspace=ws, clear_outside=False)
    # shaded where the stencil is: fragments (and the pixels fill_cracks reads) lie there
    colors, _ = shade_buffers(buffers, reflected, scene, camera.eye, incoming, stencil=stencil,
                              out=(ws.get("virtual_rgb", (h, w, 3), np.float32),
                                   ws.get("virtual_surface", (h, w), np.int32)), box=box)
    if mirror_plane is None:
        fill_cracks(colors, buffers.triangle, stencil, *box)
    return colors


def reflected_rays(primary: Primary, eye: np.ndarray, box: tuple[int, int, int, int],
                   workspace: RasterWorkspace | None = None) -> np.ndarray:
    """(H, W, 3) world: per mirror pixel of the primary pass, the direction of the eye ray
    reflected at the surface point under it (interpolated normal); NaN at the other pixels
    of `box` (rows y0..y1-1, columns x0..x1-1, holding every mirror pixel), whatever the
    last call left outside it (only mirror pixels are drawn over). For a planar mirror every
    such ray leaves the mirrored eye; for a curved one each pixel has its own viewpoint.
    `workspace`: arrays kept across frames (the result is valid until the next call)."""
    ws = workspace if workspace is not None else RasterWorkspace()
    tri = primary.buffers.triangle
    h, w = tri.shape
    r = ws.get("incoming_r", (h, w, 3), np.float64)
    buffers = primary.buffers  # barycentrics as RasterBuffers.b1, b2 would recover them
    drawn = buffers.corners if buffers.recover else None
    if drawn is None:  # a pass that kept them: recovering gives the same
        drawn = np.ascontiguousarray(primary.triangles.corners, np.float32)
    # the primary pass is drawn by rasterize, which always records its projection
    assert buffers.clip_from_world is not None, "reflected_rays needs the primary's projection"
    mirror_rays(tri, primary.frame.mirror_mask, drawn,
                np.ascontiguousarray(buffers.clip_from_world, np.float64),
                primary.triangles.corners, primary.triangles.normals,
                np.asarray(eye, np.float64), *box, r)
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
