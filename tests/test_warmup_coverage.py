"""The warm-up compiles every kernel a frame runs, so compile time is reported apart and never
inside frame 0's time: in a fresh process (numba's compiled signatures start empty), a
scene's first frame after `warm_up` adds no signature to any of reflect's kernels. The mask
(a reflector of several parts) is the scene the warm-up once missed: 18 kernels compiled (or
loaded from the cache) in its first virtual frame."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from conftest import SCENES, compiled_only

PROBE = """
import json, sys
from numba.core.registry import CPUDispatcher
from reflectcli import api

def signatures():
    return {f"{name}.{attr}": {str(s) for s in value.signatures}
            for name, module in list(sys.modules.items()) if name.startswith("reflectcli")
            for attr, value in list(vars(module).items()) if isinstance(value, CPUDispatcher)}

scene, technique, overrides = sys.argv[1], sys.argv[2], sys.argv[3:]
opened = api.open_scene(scene, technique=technique, overrides=overrides, threads=2, cache=False)
opened.warm_up()
before = signatures()
opened.prepare()
opened.render_frame(0)
after = signatures()
print(json.dumps(sorted(k for k in after if after[k] - before.get(k, set()))))
"""


@compiled_only
@pytest.mark.parametrize(("scene", "technique"), [
    ("mask", "virtual"), ("music-room", "dprm"),
    # the kernels session 27 split into a parallel part and a row part (rows claimed by
    # whichever thread is free): the distmap search, envmap lookups, ssr's rays and marches,
    # and ppr's envmap fallback on the missed pixels; lit shading on four-spheres
    ("teapot-box", "distmap"), ("teapot-box", "envmap"), ("teapot-box", "ssr"),
    ("teapot-box", "ppr"), ("four-spheres-lit", "ssr"), ("four-spheres-lit", "envmap"),
])
def test_a_first_frame_compiles_nothing_after_the_warm_up(scene, technique):
    small = ["camera.width=96", "camera.height=72"]
    done = subprocess.run([sys.executable, "-c", PROBE, str(SCENES / f"{scene}.toml"),
                           technique, *small], capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout.splitlines()[-1]) == []
