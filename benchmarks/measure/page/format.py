"""Number formats and tables of the results page (benchmarks/results_page.py), deterministic, shared by
its section renderers (measure/page/sections.py, measure/page/multi_camera.py)."""
from __future__ import annotations

import json
import statistics


# ---------------------------------------------------------------- number formats (deterministic)

def pct(x: float | None) -> str:
    """A share in [0, 1] as percent with one decimal (IoU points)."""
    return "-" if x is None else f"{100 * x:.1f}"


def pts(x: float | None) -> str:
    """A signed difference of shares as IoU points."""
    return "-" if x is None else f"{100 * x:+.1f}"


def ms(cell: dict | None, signed: bool = False) -> str:
    """``{"mean", "std"}`` of shares as 'mean ± std' points."""
    if not cell:
        return "-"
    return f"{(pts if signed else pct)(cell['mean'])} ± {100 * cell['std']:.1f}"


def num(x, digits: int = 2) -> str:
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return str(x)
    if isinstance(x, float):
        return f"{x:.{digits}f}"
    if isinstance(x, (list, tuple)) and len(x) == 2 and all(isinstance(v, int) for v in x):
        return f"{x[0]}×{x[1]}"
    if isinstance(x, (list, tuple)) and x and all(isinstance(v, (int, float)) for v in x):
        return "×".join(f"{v:.{digits}g}" for v in x)
    return json.dumps(x, ensure_ascii=False) if isinstance(x, (dict, list)) else str(x)


def table(header: list[str], rows: list[list[str]]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return out + [""]


def median3(v: list[float]) -> float:
    return sorted(v)[len(v) // 2]


def _mean_std(v: list[float] | None, signed: bool = False) -> str:
    """Values in IoU points (one per seed) as 'mean ± sample std'."""
    if not v:
        return "-"
    m, s = statistics.fmean(v), (statistics.stdev(v) if len(v) > 1 else 0.0)
    return f"{m:+.1f} ± {s:.1f}" if signed else f"{m:.1f} ± {s:.1f}"


def r_generic(d: dict) -> list[str]:
    h = d.get("headline") if isinstance(d.get("headline"), dict) else d
    rows = [[k, f"{v:.4g}" if isinstance(v, float) else num(v)] for k, v in h.items()
            if k not in ("command", "date", "machine", "data", "provenance") and not (isinstance(v, (list, dict)) and len(json.dumps(v)) > 200)]
    return table(["figure", "value"], rows)
