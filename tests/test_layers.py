"""The layers point down: config/ imports no renderer, the package has no import cycle, and
loading configs or technique parameters loads no numba."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "reflectcli"
FORBIDDEN_FOR_CONFIG = ("techniques", "raster", "trace", "maps", "virtual", "scene", "camera")


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports_of(path: Path) -> set[str]:
    """Every reflectcli module `path` imports, at top level or inside functions (absolute
    names; `from . import x` counts as importing the module x when it is one)."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith("reflectcli")}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if not target.startswith("reflectcli"):
                continue
            found.add(target)
            for a in node.names:
                found.add(f"{target}.{a.name}")
    return found


def import_graph() -> dict[str, set[str]]:
    modules = {module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph = {}
    for name, path in modules.items():
        graph[name] = {m for m in imports_of(path) if m in modules and m != name}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """A cycle of module imports (package __init__ edges to their own children excluded:
    `from . import x` in a package __init__ is how packages expose submodules), or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if nxt.startswith(node + "."):
                continue  # a package importing its own submodule
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state:
                cycle = visit(nxt)
                if cycle:
                    return cycle
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            cycle = visit(node)
            if cycle:
                return cycle
    return None


def test_config_imports_no_renderer_layer():
    bad = []
    for path in (PACKAGE / "config").rglob("*.py"):
        for target in imports_of(path):
            parts = target.split(".")
            if len(parts) > 1 and parts[1] in FORBIDDEN_FOR_CONFIG:
                bad.append(f"{module_name(path)} imports {target}")
    assert not bad, "\n".join(bad)


def test_no_import_cycle():
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_cycle_finder_reports_a_cycle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}
    assert find_cycle(graph) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def _loaded_after(statement: str) -> list[str]:
    out = subprocess.run([sys.executable, "-X", "importtime", "-c", statement],
                         capture_output=True, text=True, check=True)
    return [line.rsplit("|", 1)[-1].strip() for line in out.stderr.splitlines()
            if line.startswith("import time:") and "|" in line]


def test_config_loads_no_numba():
    loaded = _loaded_after("import reflectcli.config, reflectcli.config.load, "
                           "reflectcli.config.scene")
    assert not [m for m in loaded if m.split(".")[0] == "numba"]
    assert not [m for m in loaded if m.startswith(("reflectcli.techniques", "reflectcli.scene",
                                                   "reflectcli.raster"))]


def test_registry_params_load_no_numba():
    loaded = _loaded_after("from reflectcli.techniques.registry import PARAMS, scene_model; "
                           "scene_model()")
    assert not [m for m in loaded if m.split(".")[0] == "numba"]
