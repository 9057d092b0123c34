"""Filling an explosion map's texels (explosion.py): triangles by their texel centers, the
extension quads where still empty, and the nearest filled texel for the texels left empty,
over the whole map, or at the texels lookups will read (their ids found texel by texel,
and an empty one's nearest from the triangles themselves, nothing drawn)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _span(lo, hi, slope, cross):
    """[lo, hi] narrowed to the texels x whose center px = x + 0.5 may have
    slope * (px - cross) >= 0, with 2 texels to spare for rounding; unchanged where the
    slope is too flat to place the crossing (|slope| < 1e-6 texel units)."""
    if slope >= 1e-6:
        lo = max(lo, cross - 2.5)
    elif slope <= -1e-6:
        hi = min(hi, cross + 1.5)
    return lo, hi


@njit(cache=True, inline="always")
def _edges(ax, ay, bx, by, cx, cy, area, sign):
    """A triangle's edge functions as _fill_triangle narrows its rows by them: area * w_i
    as functions of px (w0 = e0 / area, ...), signed to be >= 0 inside, s_i px + k_i(py)
    with k_i(py) = m_i + l_i py, crossing at -k_i / s_i: (s_i, m_i, l_i, -1 / s_i) for
    each edge (no division per row)."""
    s0 = sign * (by - cy)
    s1 = sign * (cy - ay)
    s2 = -s0 - s1
    m0, l0 = sign * (bx * cy - cx * by), sign * (cx - bx)
    m1, l1 = sign * (cx * ay - ax * cy), sign * (ax - cx)
    m2, l2 = sign * area - m0 - m1, -l0 - l1
    i0 = -1.0 / s0 if s0 != 0.0 else 0.0
    i1 = -1.0 / s1 if s1 != 0.0 else 0.0
    i2 = -1.0 / s2 if s2 != 0.0 else 0.0
    return s0, m0, l0, i0, s1, m1, l1, i1, s2, m2, l2, i2


@njit(cache=True, inline="always")
def _row_span(x0, x1, edges, py):
    """The columns [lo, hi] of texels x0..x1 on the row of centers py that _fill_triangle
    tests (_span of each edge; its rounding is far inside the 2 texels to spare)."""
    s0, m0, l0, i0, s1, m1, l1, i1, s2, m2, l2, i2 = edges
    lo, hi = _span(float(x0), float(x1), s0, (m0 + l0 * py) * i0)
    lo, hi = _span(lo, hi, s1, (m1 + l1 * py) * i1)
    return _span(lo, hi, s2, (m2 + l2 * py) * i2)


@njit(cache=True, inline="always")
def _center_held(ax, ay, bx, by, cx, cy, area, sign, px, py):
    """_fill_triangle's tests of a texel center (px, py) inside its row's span. w0 = n0 /
    area < 0 exactly when sign * n0 < 0 (a quotient keeps the signs' product): the
    divisions are made only for texels both first tests pass."""
    n0 = (bx - px) * (cy - py) - (cx - px) * (by - py)
    if sign * n0 < 0.0:
        return False
    n1 = (cx - px) * (ay - py) - (ax - px) * (cy - py)
    if sign * n1 < 0.0:
        return False
    return 1.0 - n0 / area - n1 / area >= 0.0


@njit(cache=True)
def _fill_triangle(ids, ax, ay, bx, by, cx, cy, value, only_empty, box_y0=0, box_y1=1 << 30,
                   box_x0=0, box_x1=1 << 30):
    """Texels whose centers the triangle holds (barycentrics >= 0, either winding) get
    `value` (with `only_empty`, only texels still < 0). Each row visits only the span the
    three edge functions allow (widened by 2 texels) of the bounding box, then tests each
    texel exactly as before: the same texels as testing the whole box. An edge function's
    zero on row py is at cross = p + q py (p, q per triangle: no division per row; its
    rounding is far inside the 2 texels to spare). box_*: only the texels of rows
    box_y0..box_y1, columns box_x0..box_x1 (each tested as in the whole map)."""
    res = ids.shape[0]
    area = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
    if area == 0.0 or math.isnan(area):
        return
    x0 = max(int(math.floor(min(ax, bx, cx))), 0, box_x0)
    x1 = min(int(math.ceil(max(ax, bx, cx))), res - 1, box_x1)
    y0 = max(int(math.floor(min(ay, by, cy))), 0, box_y0)
    y1 = min(int(math.ceil(max(ay, by, cy))), res - 1, box_y1)
    if x0 > x1:
        return
    sign = 1.0 if area > 0.0 else -1.0
    edges = _edges(ax, ay, bx, by, cx, cy, area, sign)
    for y in range(y0, y1 + 1):
        py = y + 0.5
        lo, hi = _row_span(x0, x1, edges, py)
        if not lo <= hi:
            continue
        for x in range(int(math.ceil(lo)), int(math.floor(hi)) + 1):
            if only_empty and ids[y, x] >= 0:
                continue  # taken: no test needed
            if _center_held(ax, ay, bx, by, cx, cy, area, sign, x + 0.5, py):
                ids[y, x] = value


@njit(cache=True)
def _fill_faces(ids, coords, faces, drawn, box_y0=0, box_y1=1 << 30, box_x0=0,
                box_x1=1 << 30):
    """The drawn faces, each over the texels whose centers it holds (the last face holding
    a texel wins); box_*: as in _fill_triangle (drawing a box again, or a larger one, after
    the extensions changes nothing there: the extensions fill only texels no face holds)."""
    for k in range(drawn.shape[0]):
        fi = drawn[k]
        a, b, c = faces[fi, 0], faces[fi, 1], faces[fi, 2]
        _fill_triangle(ids, coords[a, 0], coords[a, 1], coords[b, 0], coords[b, 1],
                       coords[c, 0], coords[c, 1], fi, False, box_y0, box_y1, box_x0, box_x1)


@njit(cache=True)
def _extend(cx, cy, px, py, reach):
    dx, dy = px - cx, py - cy
    length = math.sqrt(dx * dx + dy * dy)
    if length == 0.0:
        return px, py
    return cx + dx * reach / length, cy + dy * reach / length


@njit(cache=True)
def _fill_extensions(ids, coords, extensions, n_faces, center, reach, box_y0=0,
                     box_y1=1 << 30, box_x0=0, box_x1=1 << 30):
    """Each extension's quad, where still empty (the first quad holding a texel wins);
    box_*: as in _fill_triangle."""
    for e in range(extensions.shape[0]):
        i, j = extensions[e, 1], extensions[e, 2]
        ax, ay = coords[i, 0], coords[i, 1]
        bx, by = coords[j, 0], coords[j, 1]
        cx, cy = _extend(center, center, bx, by, reach)
        dx, dy = _extend(center, center, ax, ay, reach)
        value = n_faces + e
        # either winding: _fill_triangle's barycentrics are divided by the signed area
        _fill_triangle(ids, ax, ay, bx, by, cx, cy, value, True, box_y0, box_y1, box_x0,
                       box_x1)
        _fill_triangle(ids, ax, ay, cx, cy, dx, dy, value, True, box_y0, box_y1, box_x0,
                       box_x1)


_CELL = 8  # texels a side of the cells _ids_at_marked sorts triangles into
_SMALL = 16  # texels a face may visit for _ids_at_marked to test it at once, not by cells


@njit(cache=True, inline="always")
def _texel_range(ax, ay, bx, by, cx, cy, res):
    """(x0, x1, y0, y1): the texels _fill_triangle visits for the triangle over the whole
    map (x0 > x1 if none: a degenerate or NaN triangle fills nothing)."""
    area = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
    if area == 0.0 or math.isnan(area):
        return 1, 0, 1, 0
    x0 = max(int(math.floor(min(ax, bx, cx))), 0)
    x1 = min(int(math.ceil(max(ax, bx, cx))), res - 1)
    y0 = max(int(math.floor(min(ay, by, cy))), 0)
    y1 = min(int(math.ceil(max(ay, by, cy))), res - 1)
    return x0, x1, y0, y1


@njit(cache=True, inline="always")
def _holds(ax, ay, bx, by, cx, cy, res, x, y):
    """Whether _fill_triangle fills texel (x, y) with the triangle (over the whole map, or
    over any box holding the texel: a box narrows only the texels visited): the same
    range, row span and tests, in the same arithmetic. The tests come first (most texels
    tested fail one: the range and span, with their divisions, are then not worked out),
    which changes no answer: the texel is filled exactly when all of them pass."""
    area = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
    if area == 0.0 or math.isnan(area):
        return False
    sign = 1.0 if area > 0.0 else -1.0
    py = y + 0.5
    if not _center_held(ax, ay, bx, by, cx, cy, area, sign, x + 0.5, py):
        return False
    x0, x1, y0, y1 = _texel_range(ax, ay, bx, by, cx, cy, res)
    if not (x0 <= x <= x1 and y0 <= y <= y1):
        return False
    lo, hi = _row_span(x0, x1, _edges(ax, ay, bx, by, cx, cy, area, sign), py)
    return lo <= hi and int(math.ceil(lo)) <= x <= int(math.floor(hi))


@njit(cache=True, inline="always")
def _quad(coords, extensions, e, center, reach):
    """Extension e's quad as _fill_extensions draws it: (a, b, c) and (a, c, d)."""
    i, j = extensions[e, 1], extensions[e, 2]
    ax, ay = coords[i, 0], coords[i, 1]
    bx, by = coords[j, 0], coords[j, 1]
    cx, cy = _extend(center, center, bx, by, reach)
    dx, dy = _extend(center, center, ax, ay, reach)
    return ax, ay, bx, by, cx, cy, dx, dy


@njit(cache=True)
def _marked_texels(marks, y0, y1, x0, x1):
    """(T, 2) int64 rows, columns of the marked texels of rows y0..y1, columns x0..x1, in
    row order: _ids_at_marked's `texels` where the lookups' list is not known."""
    count = 0
    for y in range(y0, y1 + 1):
        for x in range(x0, x1 + 1):
            count += marks[y, x]
    texels = np.empty((count, 2), np.int64)
    t = 0
    for y in range(y0, y1 + 1):
        for x in range(x0, x1 + 1):
            if marks[y, x]:
                texels[t, 0], texels[t, 1] = y, x
                t += 1
    return texels


@njit(cache=True)
def _ids_at_marked(ids, core, marks, coords, faces, drawn, extensions, n_faces, center,
                   reach, y0, y1, x0, x1, texels):
    """ids and core at the marked texels of rows y0..y1, columns x0..x1, as _fill_faces
    and then _fill_extensions make them (the last drawn face holding the texel, else the
    first extension quad; core: a face holds it), found texel by texel instead of drawing
    (the mask's lookups mark about 2% of their box): a face whose texels _fill_triangle
    would visit number at most _SMALL tests the marked ones among them at once, in drawing
    order, each texel keeping the last face holding it (in ids, as the face's drawing
    index: the mask's largest part has 5,130 faces of a texel or two); the larger faces
    and the quads are sorted into cells of _CELL texels that hold a marked texel, by the
    texels _fill_triangle would visit, in drawing order; a texel then tests its cell's
    larger faces from the last (down to its small face's index) and its quads from the
    first (_holds). Other texels are left as they are. True if every marked texel is
    filled (else a looked-up texel is empty: the nearest fill is needed).

    `texels` (T, 2): the marked texels of the box (row, column), every one at least once
    and no unmarked texel (the small faces test marked texels only), in any order (each
    texel's answer is its own): the lookups' list (several lookups
    may read one texel), or _marked_texels'. Scanning the box for its marks instead, twice,
    read about 50 times more texels than were marked (the mask: 787,000 for 24,000)."""
    res = ids.shape[0]
    cy0, cx0 = y0 // _CELL, x0 // _CELL
    rows, cols = y1 // _CELL - cy0 + 1, x1 // _CELL - cx0 + 1
    want = np.zeros((rows, cols), np.bool_)
    # the listed texels once each: -2 while not yet seen, then -1 (no small face holds it
    # yet)
    for t in range(texels.shape[0]):
        ids[texels[t, 0], texels[t, 1]] = -2
    unique = np.empty(texels.shape[0], np.int64)
    n_unique = 0
    for t in range(texels.shape[0]):
        y, x = texels[t, 0], texels[t, 1]
        if ids[y, x] == -2:
            ids[y, x] = -1
            want[y // _CELL - cy0, x // _CELL - cx0] = True
            unique[n_unique] = t
            n_unique += 1
    n_drawn, n_ext = drawn.shape[0], extensions.shape[0]
    # per triangle (faces, then quads), its cells' range: r0, r1, c0, c1 (empty: r0 > r1),
    # and the texels _fill_triangle visits in the box (x0, x1, y0, y1; a quad's: either
    # triangle's): a texel outside them is not held, without _holds' set-up
    span = np.empty((n_drawn + n_ext, 4), np.int64)
    rect = np.empty((n_drawn + n_ext, 4), np.int64)
    # each quad's corners, worked out once here (two square roots and four divisions;
    # made again for every texel a quad was tested at, they were a third of the tests)
    quads = np.empty((n_ext, 8))
    cap = 0  # cells of the triangles to be listed, all of them
    for k in range(n_drawn + n_ext):
        if k < n_drawn:
            f = drawn[k]
            a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
            tx0, tx1, ty0, ty1 = _texel_range(coords[a, 0], coords[a, 1], coords[b, 0],
                                              coords[b, 1], coords[c, 0], coords[c, 1], res)
        else:
            ax, ay, bx, by, cx, cy, dx, dy = _quad(coords, extensions, k - n_drawn, center,
                                                   reach)
            corner = quads[k - n_drawn]
            corner[0], corner[1], corner[2], corner[3] = ax, ay, bx, by
            corner[4], corner[5], corner[6], corner[7] = cx, cy, dx, dy
            tx0, tx1, ty0, ty1 = _texel_range(ax, ay, bx, by, cx, cy, res)
            ux0, ux1, uy0, uy1 = _texel_range(ax, ay, cx, cy, dx, dy, res)
            if ux0 <= ux1 and uy0 <= uy1:
                if tx0 <= tx1 and ty0 <= ty1:
                    tx0, tx1 = min(tx0, ux0), max(tx1, ux1)
                    ty0, ty1 = min(ty0, uy0), max(ty1, uy1)
                else:
                    tx0, tx1, ty0, ty1 = ux0, ux1, uy0, uy1
        tx0, tx1 = max(tx0, x0), min(tx1, x1)
        ty0, ty1 = max(ty0, y0), min(ty1, y1)
        if tx0 > tx1 or ty0 > ty1:
            span[k, 0], span[k, 1] = 1, 0
            continue
        if k < n_drawn and (tx1 - tx0 + 1) * (ty1 - ty0 + 1) <= _SMALL:
            # a small face: its marked texels now (a later face overwrites: the last wins)
            span[k, 0], span[k, 1] = 1, 0
            f = drawn[k]
            a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
            for y in range(ty0, ty1 + 1):
                for x in range(tx0, tx1 + 1):
                    if marks[y, x] and _holds(coords[a, 0], coords[a, 1], coords[b, 0],
                                              coords[b, 1], coords[c, 0], coords[c, 1],
                                              res, x, y):
                        ids[y, x] = k
            continue
        rect[k, 0], rect[k, 1], rect[k, 2], rect[k, 3] = tx0, tx1, ty0, ty1
        span[k, 0], span[k, 1] = ty0 // _CELL - cy0, ty1 // _CELL - cy0
        span[k, 2], span[k, 3] = tx0 // _CELL - cx0, tx1 // _CELL - cx0
        cap += (span[k, 1] - span[k, 0] + 1) * (span[k, 3] - span[k, 2] + 1)
    # each cell's faces and quads as linked items, made in one pass over the triangles'
    # cells: faces put at their cells' heads in drawing order (a cell's list then starts
    # at its last face), quads in reverse order (a list starts at its first quad).
    # Counted first, then filled, the lists read every triangle's cells twice (the mask's
    # maps: 12% more of this function's time); `cap`: the listed triangles' cells
    head = np.full((2, rows * cols), -1, np.int64)
    item = np.empty(cap, np.int64)
    nxt = np.empty(cap, np.int64)
    i = 0
    for j in range(n_drawn + n_ext):
        k = j if j < n_drawn else n_drawn + n_ext - 1 - (j - n_drawn)
        kind = 0 if k < n_drawn else 1
        for r in range(span[k, 0], span[k, 1] + 1):
            for c in range(span[k, 2], span[k, 3] + 1):
                if want[r, c]:
                    cell = r * cols + c
                    item[i] = k
                    nxt[i] = head[kind, cell]
                    head[kind, cell] = i
                    i += 1
    full = True
    for u in range(n_unique):
        y, x = texels[unique[u], 0], texels[unique[u], 1]
        cell = (y // _CELL - cy0) * cols + x // _CELL - cx0
        small = ids[y, x]  # the last small face holding it (drawing index), or -1
        found = -1
        t = head[0, cell]
        while t >= 0:
            k = item[t]
            t = nxt[t]
            if k < small:
                break  # drawn before that small face: it is the last holding the texel
            if not (rect[k, 0] <= x <= rect[k, 1] and rect[k, 2] <= y <= rect[k, 3]):
                continue
            f = drawn[k]
            a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
            if _holds(coords[a, 0], coords[a, 1], coords[b, 0], coords[b, 1],
                      coords[c, 0], coords[c, 1], res, x, y):
                found = f
                break
        if found < 0 and small >= 0:
            found = drawn[small]
        core[y, x] = found >= 0
        if found < 0:
            t = head[1, cell]
            while t >= 0:
                k = item[t]
                t = nxt[t]
                if not (rect[k, 0] <= x <= rect[k, 1] and rect[k, 2] <= y <= rect[k, 3]):
                    continue
                e = k - n_drawn
                ax, ay, bx, by = quads[e, 0], quads[e, 1], quads[e, 2], quads[e, 3]
                cx, cy, dx, dy = quads[e, 4], quads[e, 5], quads[e, 6], quads[e, 7]
                if (_holds(ax, ay, bx, by, cx, cy, res, x, y)
                        or _holds(ax, ay, cx, cy, dx, dy, res, x, y)):
                    found = n_faces + e
                    break
        ids[y, x] = found
        full &= found >= 0
    return full


@njit(cache=True)
def _clear_unmarked(layer, marks, y0, y1, x0, x1):
    """layer = -1 at the texels of rows y0..y1, columns x0..x1 that are not marked."""
    for y in range(y0, y1 + 1):
        for x in range(x0, x1 + 1):
            if not marks[y, x]:
                layer[y, x] = -1


@njit(cache=True)
def _marked_box(marks):
    """(y0, y1, x0, x1): the rows and columns holding a marked texel (y0 > y1 if none)."""
    h, w = marks.shape
    y0, y1, x0, x1 = h, -1, w, -1
    for y in range(h):
        for x in range(w):
            if marks[y, x]:
                y0 = min(y0, y)
                y1 = max(y1, y)
                x0 = min(x0, x)
                x1 = max(x1, x)
    return y0, y1, x0, x1


_FAR = 1e20  # squared distance standing for "no filled texel in this column"


@njit(cache=True)
def _nearest_filled(empty, rows, cols):
    """Exact Euclidean feature transform (Felzenszwalb & Huttenlocher's two passes of 1-D
    squared distance transforms, in O(texels)): rows[y, x], cols[y, x] is a filled (not
    empty) texel nearest to (y, x). Pass 1: per column, the nearest filled row (ties: the
    one above). Pass 2: per row, the lower envelope of the parabolas (x - x')^2 + g(x')^2
    (ties: the leftmost parabola of the envelope)."""
    h, w = empty.shape
    near_row = np.empty((h, w), np.int32)
    g = np.empty((h, w))
    for x in range(w):
        last = -1
        for y in range(h):  # nearest filled at or above
            if not empty[y, x]:
                last = y
            near_row[y, x] = last
        last = -1
        for y in range(h - 1, -1, -1):  # nearest filled at or below, if nearer
            if not empty[y, x]:
                last = y
            above = near_row[y, x]
            if last >= 0 and (above < 0 or last - y < y - above):
                near_row[y, x] = last
            r = near_row[y, x]
            g[y, x] = _FAR if r < 0 else float((y - r) * (y - r))
    v = np.empty(w, np.int64)  # parabolas of the lower envelope
    z = np.empty(w + 1)  # their ranges
    for y in range(h):
        k = 0
        v[0] = 0
        z[0] = -np.inf
        z[1] = np.inf
        for q in range(1, w):
            while True:
                p = v[k]
                s = ((g[y, q] + q * q) - (g[y, p] + p * p)) / (2.0 * (q - p))
                if s <= z[k] and k > 0:
                    k -= 1
                    continue
                break
            if s <= z[k]:  # k == 0: q replaces the first parabola
                v[0] = q
                z[1] = np.inf
                continue
            k += 1
            v[k] = q
            z[k] = s
            z[k + 1] = np.inf
        k = 0
        for x in range(w):
            while z[k + 1] < x:
                k += 1
            q = v[k]
            cols[y, x] = q
            rows[y, x] = near_row[y, q]


@njit(cache=True)
def _holes(layer, marks, reach, y0, y1, x0, x1):
    """(H, 2) rows, columns of the marked texels of rows y0..y1, columns x0..x1 that are
    empty (ids < 0), in row order; or (0, 2) and False if one lies where the whole map's
    fill could be skipped (not `reach`: the whole layer is then made), else True."""
    count = 0
    for y in range(y0, y1 + 1):
        for x in range(x0, x1 + 1):
            if marks[y, x] and layer[y, x] < 0:
                if not reach[y, x]:
                    return np.empty((0, 2), np.int64), False
                count += 1
    holes = np.empty((count, 2), np.int64)
    i = 0
    for y in range(y0, y1 + 1):
        for x in range(x0, x1 + 1):
            if marks[y, x] and layer[y, x] < 0:
                holes[i, 0], holes[i, 1] = y, x
                i += 1
    return holes, True


@njit(cache=True)
def _layer_triangles(coords, faces, drawn, extensions, n_faces, center, reach, res):
    """A layer's triangles in drawing order, as _fill_faces and then _fill_extensions draw
    them: the drawn faces, then each extension quad's two ((a, b, c), (a, c, d)): corners
    (T, 6) ax, ay, bx, by, cx, cy; value (T,) the id each writes (the face, or n_faces +
    the extension); rect (T, 4) x0, x1, y0, y1, the texels _fill_triangle visits over the
    res x res map (_texel_range: x0 > x1 if none). Made once for a layer's hole fill
    (_fill_holes), which sorts them into cells by their texels and tries each one near a
    hole (a quad's square roots worked out once)."""
    n_drawn, n_ext = drawn.shape[0], extensions.shape[0]
    count = n_drawn + 2 * n_ext
    corners = np.empty((count, 6))
    value = np.empty(count, np.int64)
    for k in range(n_drawn):
        f = drawn[k]
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        corners[k, 0], corners[k, 1] = coords[a, 0], coords[a, 1]
        corners[k, 2], corners[k, 3] = coords[b, 0], coords[b, 1]
        corners[k, 4], corners[k, 5] = coords[c, 0], coords[c, 1]
        value[k] = f
    for e in range(n_ext):
        ax, ay, bx, by, cx, cy, dx, dy = _quad(coords, extensions, e, center, reach)
        k = n_drawn + 2 * e
        corners[k, 0], corners[k, 1], corners[k, 2] = ax, ay, bx
        corners[k, 3], corners[k, 4], corners[k, 5] = by, cx, cy
        corners[k + 1, 0], corners[k + 1, 1], corners[k + 1, 2] = ax, ay, cx
        corners[k + 1, 3], corners[k + 1, 4], corners[k + 1, 5] = cy, dx, dy
        value[k] = value[k + 1] = n_faces + e
    rect = np.empty((count, 4), np.int64)
    for k in range(count):
        x0, x1, y0, y1 = _texel_range(corners[k, 0], corners[k, 1], corners[k, 2],
                                      corners[k, 3], corners[k, 4], corners[k, 5], res)
        rect[k, 0], rect[k, 1], rect[k, 2], rect[k, 3] = x0, x1, y0, y1
    return corners, value, rect


@njit(cache=True, inline="always")
def _before(d, x, y, bd, bx, by):
    """Whether texel (x, y) at squared distance d comes before (bx, by) at bd by the whole
    map's rule (_nearest_filled): least squared distance, then least column, then least
    row."""
    return d < bd or (d == bd and (x < bx or (x == bx and y < by)))


@njit(cache=True)
def _nearest_held(corner, rect, hy, hx, bd, bx, by):
    """The texel a triangle fills (_fill_triangle over the whole map: corner (6,) ax, ay, bx,
    by, cx, cy; rect its texels, _texel_range) that comes first by the whole map's rule for
    the texel (hy, hx), if it comes before (bx, by) at squared distance bd; else
    (bd, bx, by). Rows from the hole's outward, each tested from the hole's column outward
    within its span (left before right: the lesser column wins a tie), while a texel could
    still come first."""
    ax, ay, qx, qy, cx, cy = (corner[0], corner[1], corner[2], corner[3], corner[4],
                              corner[5])
    area = (qx - ax) * (cy - ay) - (cx - ax) * (qy - ay)
    x0, x1, y0, y1 = rect[0], rect[1], rect[2], rect[3]
    sign = 1.0 if area > 0.0 else -1.0
    edges = _edges(ax, ay, qx, qy, cx, cy, area, sign)
    yc = min(max(hy, y0), y1)
    for direction in range(2):
        y = yc if direction == 0 else yc - 1
        while y0 <= y <= y1:
            dy2 = (y - hy) * (y - hy)
            if dy2 > bd:
                break
            py = y + 0.5
            lo, hi = _row_span(x0, x1, edges, py)
            if lo <= hi:
                xa, xb = int(math.ceil(lo)), int(math.floor(hi))
                # columns in the order of their distance from hx, the lesser first
                j = max(xa - hx, hx - xb, 0)
                while True:
                    d = dy2 + j * j
                    if d > bd or (hx - j < xa and hx + j > xb):
                        break
                    x = hx - j
                    if xa <= x <= xb and _center_held(ax, ay, qx, qy, cx, cy, area, sign,
                                                      x + 0.5, py):
                        if _before(d, x, y, bd, bx, by):
                            bd, bx, by = d, x, y
                        break
                    x = hx + j
                    if j > 0 and xa <= x <= xb and _center_held(ax, ay, qx, qy, cx, cy, area,
                                                                sign, x + 0.5, py):
                        if _before(d, x, y, bd, bx, by):
                            bd, bx, by = d, x, y
                        break
                    j += 1
            y = y + 1 if direction == 0 else y - 1
    return bd, bx, by


_HOLE_CELL = 8  # texels a side of the cells _fill_holes sorts the triangles into
# _fill_holes' work (texel pairs compared, cells and triangles tried; a triangle's nearest
# texel counts 16) allowed per texel of the map before the whole layer is made instead
# (its draws and nearest fill: 0.6 ms at 200 x 200): many holes far from any filled texel
# (an open patch's lookups landing mostly outside it) would cost more searched one by one
_HOLE_WORK = 8


@njit(cache=True)
def _fill_holes(layer, texels, holes, corners, value, rect, n_drawn):
    """Each hole (holes (H, 2) rows, columns: marked texels left empty) given the id of its
    nearest filled texel by the whole map's rule, as the whole layer's nearest fill gives
    it, without drawing: a texel is filled where one of the layer's triangles
    (_layer_triangles: corners, value, rect) holds it, so the nearest is the first of each
    triangle's own nearest (_nearest_held), and its id the last face holding it, else the
    first quad (as _fill_faces and _fill_extensions draw). The looked-up texels already
    filled (texels (T, 2), their ids in `layer`) bound each hole's search first; the
    triangles whose texels lie within the farthest bound of the holes' box (one holding
    a texel nearer than a bound is among them) are sorted into cells of _HOLE_CELL
    texels by their texels, in drawing order, and each hole tries its cell's triangles,
    then each ring of cells around it, until no texel of the next ring can come first.
    `holes`: at least one, in row order (_holes'). Returns False, writing nothing, if a
    hole has no filled texel (a layer with nothing filled), or when the search would
    take more than _HOLE_WORK units a texel of the map: the whole layer's build then
    takes over. The holes are written last (each hole is empty to the others'
    searches)."""
    res = layer.shape[0]
    count = holes.shape[0]
    budget = _HOLE_WORK * res * res
    work = count * texels.shape[0]
    if work > budget:
        return False
    best = np.empty((count, 3), np.int64)  # squared distance, column, row
    far = 1 << 62
    for i in range(count):
        hy, hx = holes[i, 0], holes[i, 1]
        bd, bx, by = far, -1, -1
        for t in range(texels.shape[0]):
            y, x = texels[t, 0], texels[t, 1]
            if layer[y, x] >= 0:
                d = (y - hy) * (y - hy) + (x - hx) * (x - hx)
                if _before(d, x, y, bd, bx, by):
                    bd, bx, by = d, x, y
        best[i, 0], best[i, 1], best[i, 2] = bd, bx, by
    # the cells: over the holes' box grown by the farthest bound (in the map)
    gy0, gy1 = holes[0, 0], holes[count - 1, 0]
    gx0, gx1 = holes[0, 1], holes[0, 1]
    bound = 0
    for i in range(count):
        gx0, gx1 = min(gx0, holes[i, 1]), max(gx1, holes[i, 1])
        bound = max(bound, best[i, 0])
    grow = res if bound == far else int(math.sqrt(bound)) + 1
    gy0, gy1 = max(gy0 - grow, 0), min(gy1 + grow, res - 1)
    gx0, gx1 = max(gx0 - grow, 0), min(gx1 + grow, res - 1)
    rows = (gy1 - gy0) // _HOLE_CELL + 1
    cols = (gx1 - gx0) // _HOLE_CELL + 1
    start = np.zeros(rows * cols + 1, np.int64)
    for step in range(2):  # counted, then filled
        if step == 1:
            for c in range(rows * cols):
                start[c + 1] += start[c]
            items = np.empty(start[rows * cols], np.int64)
            fill = start[:rows * cols].copy()
        for k in range(corners.shape[0]):
            x0, x1 = max(rect[k, 0], gx0), min(rect[k, 1], gx1)
            y0, y1 = max(rect[k, 2], gy0), min(rect[k, 3], gy1)
            if x0 > x1 or y0 > y1:
                continue  # fills nothing here (or nothing at all: x0 > x1)
            for r in range((y0 - gy0) // _HOLE_CELL, (y1 - gy0) // _HOLE_CELL + 1):
                for c in range((x0 - gx0) // _HOLE_CELL, (x1 - gx0) // _HOLE_CELL + 1):
                    if step == 0:
                        start[r * cols + c + 1] += 1
                    else:
                        items[fill[r * cols + c]] = k
                        fill[r * cols + c] += 1
    work += start[rows * cols]
    tried = np.full(corners.shape[0], -1, np.int64)  # the hole that last tried a triangle
    for i in range(count):
        hy, hx = holes[i, 0], holes[i, 1]
        bd, bx, by = best[i, 0], best[i, 1], best[i, 2]
        hr, hc = (hy - gy0) // _HOLE_CELL, (hx - gx0) // _HOLE_CELL
        ring = 0
        while True:
            if ring > 0:
                gap = (ring - 1) * _HOLE_CELL + 1  # texels from the hole to the ring, at least
                if gap * gap > bd:
                    break
            if hr - ring < 0 and hc - ring < 0 and hr + ring >= rows and hc + ring >= cols:
                break  # the ring lies outside the cells
            for r in range(max(hr - ring, 0), min(hr + ring, rows - 1) + 1):
                edge = r == hr - ring or r == hr + ring
                step = 1 if edge or ring == 0 else 2 * ring
                for c in range(hc - ring, hc + ring + 1, step):
                    if c < 0 or c >= cols:
                        continue
                    cell = r * cols + c
                    work += 1 + start[cell + 1] - start[cell]
                    for t in range(start[cell], start[cell + 1]):
                        k = items[t]
                        if tried[k] == i:
                            continue
                        tried[k] = i
                        gx = max(rect[k, 0] - hx, hx - rect[k, 1], 0)
                        gy = max(rect[k, 2] - hy, hy - rect[k, 3], 0)
                        if gx * gx + gy * gy <= bd:
                            work += 16
                            bd, bx, by = _nearest_held(corners[k], rect[k], hy, hx, bd, bx,
                                                       by)
            if work > budget:
                return False
            ring += 1
        if bx < 0:
            return False
        best[i, 0], best[i, 1], best[i, 2] = bd, bx, by
    ids = np.empty(count, np.int32)
    for i in range(count):
        x, y = best[i, 1], best[i, 2]
        cell = ((y - gy0) // _HOLE_CELL) * cols + (x - gx0) // _HOLE_CELL
        ids[i] = -1
        for t in range(start[cell + 1] - 1, start[cell] - 1, -1):  # the last face holding it
            k = items[t]
            if k < n_drawn and _holds_at(corners[k], rect[k], res, x, y):
                ids[i] = value[k]
                break
        if ids[i] < 0:
            for t in range(start[cell], start[cell + 1]):  # else the first quad
                k = items[t]
                if k >= n_drawn and _holds_at(corners[k], rect[k], res, x, y):
                    ids[i] = value[k]
                    break
    for i in range(count):
        layer[holes[i, 0], holes[i, 1]] = ids[i]
    return True


@njit(cache=True, inline="always")
def _holds_at(corner, rect, res, x, y):
    """Whether the triangle (corner, rect: _nearest_held's) fills texel (x, y): _holds."""
    if not (rect[0] <= x <= rect[1] and rect[2] <= y <= rect[3]):
        return False
    return _holds(corner[0], corner[1], corner[2], corner[3], corner[4], corner[5], res,
                  x, y)
