"""Every repository path the README, docs/*.md and the package's docstrings mention exists.

A path is a word starting with one of the repository's top-level folders (`reflectcli/...`,
`scenes/...`, `configs/...`, `scripts/...`, `benchmarks/...`, `docs/...`, `tests/...`) or a
top-level Markdown file name (`README.md`), backticked or not. Paths in docstrings may be
written relative to the package (`maps/lookup.py` for reflectcli/maps/lookup.py). Paths
with a placeholder (`techniques/<name>/`) and generated folders (`.reflect-cache/`) are
skipped."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "reflectcli"
TOP = ("reflectcli", "scenes", "configs", "scripts", "benchmarks", "docs", "tests")
END = r"(?!<|\*|[\w/-]|\.[\w/])"  # a path ends where no path character, placeholder or glob follows
PATH = re.compile(r"(?<![\w./-])((?:" + "|".join(TOP) + r")/[\w./-]*[\w/]|[A-Z][A-Z_]*\.md)" + END)
# package-relative module paths in docstrings: `maps/lookup.py`, `virtual/`
SUBPACKAGES = tuple(p.name for p in PACKAGE.iterdir() if p.is_dir() and p.name != "__pycache__")
RELATIVE = re.compile(r"(?<![\w./-])((?:" + "|".join(SUBPACKAGES) + r")/[\w./-]*\.py)" + END)


def mentioned(text: str, relative: bool = False) -> set[str]:
    found = {m.rstrip(".") for m in PATH.findall(text)}
    if relative:
        found |= {"reflectcli/" + m for m in RELATIVE.findall(text)}
    # generated folders (`scenes/.reflect-cache/`) are not in the repository
    return {p for p in found if "/." not in p}


def docstrings(path: Path) -> str:
    tree = ast.parse(path.read_text(), str(path))
    nodes = [tree] + [n for n in ast.walk(tree)
                      if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef)]
    return "\n".join(ast.get_docstring(n) or "" for n in nodes)


def missing(paths: set[str]) -> list[str]:
    return sorted(p for p in paths if not (ROOT / p).exists())


def test_readme_and_docs_name_existing_files():
    bad = []
    for doc in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        bad += [f"{doc.relative_to(ROOT)}: {p}" for p in missing(mentioned(doc.read_text()))]
    assert not bad, "\n".join(bad)


def test_docstrings_name_existing_files():
    bad = []
    for path in sorted(PACKAGE.rglob("*.py")):
        paths = mentioned(docstrings(path), relative=True)
        bad += [f"{path.relative_to(ROOT)}: {p}" for p in missing(paths)]
    assert not bad, "\n".join(bad)


def test_the_extraction_finds_paths():
    text = ("see `reflectcli/maps/lookup.py`, scenes/teapot-box.toml, (configs/bench/x.toml), "
            "`ARCHITECTURE.md`; not out/bench/ nor reflectcli/techniques/<name>/ nor "
            "scenes/.reflect-cache/. Ends: reflectcli/api.py.")
    assert mentioned(text) == {"reflectcli/maps/lookup.py", "scenes/teapot-box.toml",
                               "configs/bench/x.toml", "ARCHITECTURE.md", "reflectcli/api.py"}
    assert "reflectcli/maps/lookup.py" in mentioned("as in maps/lookup.py:", relative=True)
    assert missing({"reflectcli/api.py", "docs/nowhere.md"}) == ["docs/nowhere.md"]
