"""Map update policies shared by the map techniques (envmap, dprm, distmap): which frame's
geometry each map (or cube face) of frame `frame_index` is captured from.

`update = "once"`: every map is captured at frame 0 (moving objects stay where they were).
`update = "every"`: recaptured every frame. `update = N`: recaptured at frames 0, N, 2N, ...
`faces_per_frame = F` (cube maps, time slicing as engines do it): each update refreshes only
F of the six faces, round robin (update u refreshes faces (u F + j) mod 6, j < F); frame 0
always captures all six. With F = 6 every update refreshes the whole cube.

A pure function of the frame index, so a frame's maps do not depend on which frames were
rendered before it (`--frames` subsets and `--resume` give the same images).
"""

from __future__ import annotations

FACES = 6


def update_interval(update) -> int | None:
    """Frames between updates: None for "once", 1 for "every", else N."""
    if update == "once":
        return None
    if update == "every":
        return 1
    return int(update)


def map_capture_frame(frame_index: int, update) -> int:
    """The frame whose geometry a whole map used at `frame_index` is captured from."""
    n = update_interval(update)
    return 0 if n is None else n * (frame_index // n)


def face_capture_frames(frame_index: int, update, faces_per_frame: int = FACES) -> list[int]:
    """Per cube face (+x, -x, +y, -y, +z, -z), the frame its capture used at `frame_index`
    comes from."""
    n = update_interval(update)
    if n is None:
        return [0] * FACES
    u = frame_index // n
    f_per = min(max(int(faces_per_frame), 1), FACES)
    out = []
    for face in range(FACES):
        found = 0
        for v in range(u, max(0, u - FACES), -1):
            if any((v * f_per + j) % FACES == face for j in range(f_per)):
                found = v
                break
        out.append(n * found)
    return out


def faces_updated(frame_index: int, update, faces_per_frame: int = FACES) -> int:
    """How many cube faces frame `frame_index` captures (all six at frame 0)."""
    if frame_index == 0:
        return FACES
    now = face_capture_frames(frame_index, update, faces_per_frame)
    before = face_capture_frames(frame_index - 1, update, faces_per_frame)
    return sum(a != b for a, b in zip(now, before, strict=True))
