"""Statistics over seeds: :func:`seed_stats` (mean, std, per seed), :func:`format_stat` ('mean ± std'),
paired differences (:func:`paired`) and the cells of a study (:func:`aggregate`).
"""
from __future__ import annotations

import numpy as np

# crossval conditions without a model of their own (no convergence, no in-domain target, no no-change reference)
UNTRAINED = ("prior", "adapt", "adapt-fuse")
ADAPTED = ("adapt", "adapt-fuse")  # reported as paired differences to within


def seed_stats(v: list[float]) -> dict:
    """Mean, sample std (ddof 1; 0 for one value) and the values of ``v``, one per seed."""
    a = np.asarray(v, float)
    return {"mean": float(a.mean()) if len(a) else None, "std": float(a.std(ddof=1)) if len(a) > 1 else 0.0,
            "per_seed": [float(x) for x in a]}


def format_stat(s: dict | None, scale: float = 100.0, signed: bool = False) -> str:
    """A :func:`seed_stats` as 'mean ± std' x ``scale`` (IoU points), '-' where there is none."""
    if not s or s["mean"] is None:
        return "-"
    return f"{scale * s['mean']:{'+' if signed else ''}.1f} ± {scale * s['std']:.1f}"


def paired(per_seed: dict[int, dict], sets: list[str], groups: dict[str, list[str]], a: str, b: str) -> dict:
    """Paired differences a - b of road IoU per seed (mean, std, per seed), per test set and group
    (a group's difference per seed is the mean over its members)."""
    seeds = sorted(per_seed)
    diff: dict[str, dict] = {}
    for s in sets:
        diff[s] = seed_stats([per_seed[k][s, a]["iou"] - per_seed[k][s, b]["iou"] for k in seeds
                              if (s, a) in per_seed[k] and (s, b) in per_seed[k]])
    for g, members in groups.items():
        if members:
            diff[g] = seed_stats([float(np.mean([per_seed[k][m, a]["iou"] - per_seed[k][m, b]["iou"]
                                                 for m in members]))
                                  for k in seeds if all((m, c) in per_seed[k] for m in members for c in (a, b))])
    return diff


def aggregate(per_seed: dict[int, dict], sets: list[str], conditions: list[str],
              groups: dict[str, list[str]]) -> dict:
    """Cells (mean, std, per seed) and paired within - resize (and adapt - within) differences, per
    test set and group (``groups``: name -> its test sets; a group's value per seed is the mean over
    them)."""
    seeds = sorted(per_seed)
    cells: dict[str, dict[str, dict]] = {}
    for s in sets:
        cells[s] = {c: seed_stats([per_seed[k][s, c]["iou"] for k in seeds if (s, c) in per_seed[k]])
                    for c in conditions}
    for g, members in groups.items():
        if members:
            cells[g] = {c: seed_stats([float(np.mean([per_seed[k][m, c]["iou"] for m in members])) for k in seeds
                                       if all((m, c) in per_seed[k] for m in members)]) for c in conditions}
    diff = paired(per_seed, sets, groups, "within", "resize") if {"within", "resize"} <= set(conditions) else {}
    adapt = {c: paired(per_seed, sets, groups, c, "within") for c in ADAPTED if {c, "within"} <= set(conditions)}
    vp = paired(per_seed, sets, groups, "within", "between") if {"within", "between"} <= set(conditions) else {}
    return {"cells": cells, "within_minus_resize": diff, "adapt_minus_within": adapt, "within_minus_between": vp,
            "groups": groups}
