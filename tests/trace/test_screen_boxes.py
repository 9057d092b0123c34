"""analytic.screen_boxes: no primary ray outside a mirror's box can meet the mirror (the
primary wave traces analytic mirrors only inside the boxes, so a box that is too small would
drop mirror hits)."""

from __future__ import annotations

import numpy as np
import pytest

from reflectcli.camera import Camera
from reflectcli.scene.types import CYLINDER, MESH, MIRROR_PARAMS, PLANAR, SPHERE
from reflectcli.trace.analytic import intersect_analytic, screen_boxes
from reflectcli.trace.rays import primary_rays


def random_mirrors(rng):
    """A quad, a sphere and a cylinder near the origin, and a mesh mirror (no box)."""
    kind = np.array([PLANAR, SPHERE, CYLINDER, MESH], np.int32)
    params = np.zeros((4, MIRROR_PARAMS))
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    e1 = np.cross(n, rng.normal(size=3))
    e1 *= rng.uniform(0.5, 3.0) / np.linalg.norm(e1)
    e2 = np.cross(n, e1) * rng.uniform(0.3, 1.5)
    c00 = rng.uniform(-2, 2, 3)
    params[0, :16] = (*n, -n @ c00, *c00, *(c00 + e1), *(c00 + e1 + e2), *(c00 + e2))
    params[1, :4] = (*rng.uniform(-2, 2, 3), rng.uniform(0.2, 1.5))
    a = rng.normal(size=3)
    params[2, :8] = (*rng.uniform(-2, 2, 3), *(a / np.linalg.norm(a)), rng.uniform(0.2, 1.0),
                     rng.uniform(0.5, 3.0))
    return kind, params


@pytest.mark.parametrize("seed", range(12))
def test_every_mirror_hit_lies_in_its_box(seed):
    rng = np.random.default_rng(seed)
    kind, params = random_mirrors(rng)
    # cameras near the mirrors, some inside their bounds (whole-image boxes)
    eye = rng.uniform(-6, 6, 3) if seed % 3 else rng.uniform(-1.5, 1.5, 3)
    camera = Camera(eye, rng.uniform(-1, 1, 3), np.array([0.0, 1.0, 0.0]),
                    float(rng.uniform(30, 90)), 48, 36, 0.05, 100.0)
    samples = 1 + seed % 2
    origins, dirs = primary_rays(camera, samples)
    boxes = screen_boxes(kind, params, camera)
    assert (boxes[3] == 0).all()
    h, w, s = camera.height, camera.width, samples
    for k in range(3):
        one = np.zeros_like(kind) + MESH
        one[k] = kind[k]
        t, idx = intersect_analytic(origins, dirs, np.full(len(dirs), 99.95, np.float32), one,
                                    params, 0.0)
        hit = (idx == k).reshape(h, w, s, s).any(axis=(2, 3))
        rows, cols = np.nonzero(hit)
        x0, x1, y0, y1 = boxes[k]
        assert ((cols >= x0) & (cols < x1) & (rows >= y0) & (rows < y1)).all(), (k, boxes[k])


def test_a_mirror_around_the_eye_gets_the_whole_image():
    kind = np.array([SPHERE], np.int32)
    params = np.zeros((1, MIRROR_PARAMS))
    params[0, :4] = (0.0, 0.0, 0.0, 2.0)
    camera = Camera(np.array([0.0, 0.0, 0.5]), np.zeros(3), np.array([0.0, 1.0, 0.0]), 60.0,
                    20, 10, 0.01, 10.0)
    np.testing.assert_array_equal(screen_boxes(kind, params, camera), [[0, 20, 0, 10]])
