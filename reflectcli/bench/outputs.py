"""The bench's files from its rows: results.csv, report.md and (with the plots extra) plots."""

from __future__ import annotations

import os

from .report import report_markdown, write_csv, write_text


def write_outputs(plan, rows: list[dict]) -> None:
    out = plan.out
    write_csv(os.path.join(out, "results.csv"), rows)
    write_text(os.path.join(out, "report.md"), report_markdown(plan.config.bench.name, rows))
    if plan.config.bench.plots:
        try:
            from .plots import write_plots
        except ImportError:
            return  # matplotlib is an optional extra
        write_plots(out, rows)
