"""The tables of a cross-camera study (:mod:`vctrain.study`): its result rows, summarised.

One row per evaluated dataset and condition (``heldout``, ``condition``, road ``iou`` and the
run's facts); the table has the evaluated datasets (and their mean) as rows, the conditions as
columns and road IoU x 100 in the cells ('-': no run). :func:`write_tables` writes OUT/
``results.jsonl`` (the rows), ``table.md``, ``table.csv`` and ``summary.json`` ({condition: mean
road IoU}); every file is written atomically, JSON with sorted keys (:func:`write_json`).
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from vcprep.io import write_bytes_atomic

__all__ = ["summary_of", "format_table", "write_tables", "write_json"]


def write_json(path: Path, obj: Any) -> None:
    """``obj`` as JSON (indent 1, sorted keys, a final newline), written atomically."""
    write_bytes_atomic(path, (json.dumps(obj, indent=1, sort_keys=True) + "\n").encode())


def summary_of(rows: Sequence[dict[str, Any]], conditions: Sequence[str]) -> dict[str, float]:
    """Condition -> mean road IoU over the evaluated datasets that have a result for it."""
    out = {}
    for c in conditions:
        v = [r["iou"] for r in rows if r["condition"] == c]
        if v:
            out[c] = float(np.mean(v))
    return out


def format_table(rows: Sequence[dict[str, Any]], heldout: Sequence[str], conditions: Sequence[str],
                 fmt: str = "md") -> str:
    """Rows: evaluated (held-out or test-role) dataset + mean; columns: conditions; cells: road IoU x 100
    ('-' = no run)."""
    cell = {(r["heldout"], r["condition"]): r["iou"] for r in rows}
    mean = summary_of(rows, conditions)
    body = [[h] + [f"{100 * cell[h, c]:.1f}" if (h, c) in cell else "-" for c in conditions] for h in heldout]
    body.append(["mean"] + [f"{100 * mean[c]:.1f}" if c in mean else "-" for c in conditions])
    header = ["held out"] + list(conditions)
    if fmt == "csv":
        return "\n".join(",".join(r) for r in [header] + body) + "\n"
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in body]
    return "\n".join(lines) + "\n"


def write_tables(out: Path, rows: Sequence[dict[str, Any]], heldout: Sequence[str], conditions: Sequence[str],
                 notes: Sequence[str] = ()) -> None:
    """The study's result files in ``out``: the rows (``results.jsonl``), the table (``table.md``
    with ``notes`` below it, ``table.csv``) and ``summary.json``."""
    write_bytes_atomic(out / "results.jsonl", "".join(json.dumps(r, sort_keys=True) + "\n" for r in rows).encode())
    write_bytes_atomic(out / "table.md", ("Road IoU (%) on each evaluated dataset's test images (never "
                                          "trained on), scored in its own camera.\n\n" + format_table(rows, heldout, conditions)
                                          + "".join(f"\n{n}\n" for n in notes)).encode())
    write_bytes_atomic(out / "table.csv", format_table(rows, heldout, conditions, "csv").encode())
    write_json(out / "summary.json", summary_of(rows, conditions))
