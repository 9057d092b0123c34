"""The bench's own folders and files, checked before anything is written (by `validate` and
`bench` alike): nothing of the bench's is written through a link or outside its `out`, and
every refusal is one line naming the bench file's `bench.out` (or `--out`), exit code 2,
not a write failure (exit 1) after the references were rendered and results.jsonl dropped.
"""

from __future__ import annotations

import os

from ..errors import Problem, Problems
from ..output.names import LOCK_NAME
from ..output.paths import check_links, check_writable

RESULT_FILES = ("results.jsonl", "results.csv", "report.md")
APPENDED = "results.jsonl"  # appended to in place (`--resume`); the others are replaced


def check_bench_folder(plan, source: str, field: str) -> None:
    """Refuse in one line: a folder of the bench's own (references, runs, cache, each run's
    or reference's folder under them, and a reference's frame folder, which is rendered again
    in place) that is a link, is not a folder, or resolves outside `out`; a link in a
    reference's frame folder at a name its render writes; a link or a non-file at a result
    file's or the lock's name; and a results.jsonl with other hard links (its rows would land
    in that file too). A run's own frame folder is removed before the run renders, so a link
    in it is dropped, never written through. The folder itself must be one `bench` can
    make or write into (a file at its name was "[Errno 17] File exists")."""
    check_writable(plan.out, source, field)
    top = os.path.realpath(plan.out)
    subs = ["references", "runs", "cache"]
    for job in plan.jobs:
        subs += [os.path.join("references", job["reference"]["id"]),
                 os.path.join("runs", job["id"])]
    for sub in dict.fromkeys(subs):
        path = os.path.join(plan.out, sub)
        if not os.path.lexists(path):
            continue
        real = os.path.realpath(path)
        if os.path.islink(path):
            why = "is a symbolic link; reflect writes nothing through a link (remove it)"
        elif os.path.commonpath([top, real]) != top:
            why = (f"leads to '{real}', outside {plan.out}; reflect writes nothing outside "
                   "its output folder")
        elif not os.path.isdir(path):
            why = "is not a folder (remove it)"
        else:
            continue
        raise Problems([Problem(source, field, f"'{path}' {why}")])
    _check_reference_folders(plan, source, field)
    for name in (*RESULT_FILES, LOCK_NAME):
        path = os.path.join(plan.out, name)
        if os.path.islink(path):
            why = "is a symbolic link; reflect writes no file through a link (remove it)"
        elif os.path.lexists(path) and not os.path.isfile(path):
            why = "is not a regular file (remove it)"
        elif name == APPENDED and os.path.lexists(path) and os.lstat(path).st_nlink > 1:
            why = ("has other hard links; reflect appends to no file that has another name "
                   "(copy it, or remove it)")
        else:
            continue
        raise Problems([Problem(source, field, f"'{path}' {why}")])


def _check_reference_folders(plan, source: str, field: str) -> None:
    """Each reference's <scene>/raytrace/ folder as its render (resumed in place) checks it
    (paths.check_links), refused in the bench's words: that render named `--out`."""
    for job in plan.jobs:
        ref = job["reference"]
        root = os.path.join(plan.out, "references", ref["id"])
        try:
            check_links(root, os.path.join(root, ref["scene_name"], "raytrace"), ref["log"],
                        source, field, source)
        except Problems as e:
            raise Problems([Problem(source, field, p.message) for p in e.problems]) from None
