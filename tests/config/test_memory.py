"""The memory estimate (config/memory.py) against what renders were measured to need."""

from __future__ import annotations

import pytest
from test_cli import TINY as SCENE

from reflectcli.config import memory
from reflectcli.errors import Problems
from reflectcli.loading import load_config

GiB = 1 << 30


@pytest.fixture
def here(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    return tmp_path


def distmap(here, resolution: int, layers: int, mirrors: int = 1):
    extra = "".join(f'\n[[mirrors]]\nname = "m{k}"\nshape = "quad"\n'
                    f"corners = [[-2, 0, -{k}], [2, 0, -{k}], [2, 1, -{k}], [-2, 1, -{k}]]\n"
                    for k in range(1, mirrors))
    path = here / "d.toml"
    path.write_text(SCENE + extra + '\n[technique]\nname = "distmap"\n'
                    f"resolution = {resolution}\nlayers = {layers}\n")
    return str(path)


def map_bytes(path: str) -> int:
    cfg, _ = load_config(path)
    return memory.estimate(cfg, path)[1][("technique",)]


def test_distmap_maps_count_their_layers(here):
    """resolution 1024 with 8 layers on a scene of one mirror peaked at 2.48 GiB (maxrss of
    `reflect render`, the warm-up's maps made small; 6.06 GiB when it captured five mirrors'
    full-size maps; the estimate once said 480 MiB, as for 1 layer)."""
    one, eight = map_bytes(distmap(here, 1024, 1)), map_bytes(distmap(here, 1024, 8))
    assert eight - one == 7 * 6 * 1024**2 * (memory.DISTMAP_BYTES_KEPT
                                            + memory.DISTMAP_BYTES_STORING)
    assert eight >= 2.48 * GiB
    assert eight < 5 * GiB  # generous, not absurd


def test_distmap_maps_count_every_mirror(here):
    """Each mirror keeps its own layered cube map."""
    texels = 4 * 6 * 256**2
    two, three = (map_bytes(distmap(here, 256, 4, mirrors=m)) for m in (2, 3))
    assert three - two == texels * memory.DISTMAP_BYTES_KEPT


def test_distmap_past_this_machines_memory_is_one_line(here, monkeypatch):
    """resolution 4096 with 8 layers (about 46 GiB) validated on a 22 GiB machine."""
    monkeypatch.setattr(memory, "available_bytes", lambda: 22 * GiB)
    with pytest.raises(Problems) as info:
        load_config(distmap(here, 4096, 8))
    assert [str(p) for p in info.value.problems] == [
        "d.toml: technique: this render needs about 46.3 GiB of memory; 22.0 GiB is available"]
    load_config(distmap(here, 1024, 4))  # 1.5 GiB: fine


def test_clutter_counts_the_triangles_it_asks_for(here, monkeypatch):
    """The estimate took twice `triangles`: a clutter of 15M (its field allows 20M) was
    refused as "about 30,000,050 triangles; the limit is 20,000,000". Measured: 1,600 at 500,
    189,990 at 190,000, 14,999,996 at 15M, 19,999,812 at 20M."""
    from reflectcli.scene.procedural import music_room_clutter

    monkeypatch.setattr(memory, "available_bytes", lambda: 1 << 50)
    path = here / "c.toml"
    for asked in (500, 20_000, 15_000_000):
        path.write_text(SCENE + '\n[[objects]]\nname = "c"\nshape = "clutter"\n'
                        f'triangles = {asked}\nmin = [-2, 0, -2]\nmax = [2, 2, 2]\n'
                        'material = "red"\n')
        cfg, _ = load_config(str(path))  # within the limit
        estimate = memory.triangles(cfg.objects[-1], str(path))
        assert asked <= estimate <= max(asked, 2_000) * 1.01
        if asked < 1_000_000:
            built = music_room_clutter(asked, (-2, 0, -2), (2, 2, 2)).triangle_count
            assert built <= estimate
