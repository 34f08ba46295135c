"""Markdown tables and the bar plot of a study's statistics (:func:`shift_table`, :func:`seed_table`,
:func:`bar_plot`: OpenCV, no matplotlib).
"""
from __future__ import annotations

import cv2
import numpy as np

from .stats import UNTRAINED, format_stat


def shift_table(shift: dict, conditions: list[str]) -> list[str]:
    """Markdown lines: the camera change alone (empty without simulated sets)."""
    sims = [n for n in shift["reference"] if shift["reference"][n]]
    if not sims:
        return []
    trained = [c for c in conditions if c not in UNTRAINED and all(c in shift["reference"][n] for n in sims)]
    lines = ["The camera change alone: each model's prediction on the simulations' source frames in their own "
             "camera, carried into the simulated camera by the exact simulation homography and scored there "
             "(same frames, same pixels, no camera change), and the cost of the change = the score on the "
             "camera − that (road IoU points, mean ± std over seeds):", "",
             "| simulated set | " + " | ".join(f"{c}: no change | {c}: cost" for c in trained) + " |",
             "|---|" + "---|---|" * len(trained)]
    for n in sims + (["simulated"] if "simulated" in shift["cost"] else []):
        row = [n if n in sims else "**simulated** (mean)"]
        for c in trained:
            row += [format_stat(shift["reference"][n].get(c)) if n in sims else "",
                    format_stat(shift["cost"][n].get(c), signed=True)]
        lines.append("| " + " | ".join(row) + " |")
    b = shift["zero_cost"]
    if b:
        parts = [f"{n} {format_stat(b[n], signed=True)}" for n in sims if n in b]
        lines += ["", "within − resize if the within model lost nothing to the camera change (within's no-change "
                  "score − resize's score; what these test sets allow at this network quality): " + ", ".join(parts)
                  + (f"; simulated mean **{format_stat(b['simulated'], signed=True)}**" if "simulated" in b else "")
                  + (f"; other cameras (KITTI as measured) **{format_stat(b['other cameras'], signed=True)}**"
                     if "other cameras" in b else "") + "."]
    v = shift.get("exact_vp") or {}
    if v:
        lines += ["", "within with each frame's EXACT camera pose (the simulation's, as a perfect per-frame "
                  "calibration gives) instead of its estimated road VP (same model, same virtual camera): "
                  + ", ".join(f"{n} {format_stat(v[n]['exact'])} (estimated − exact: "
                              f"{format_stat(v[n]['cost'], signed=True)})" for n in v) + "."]
    return lines + [""]


def seed_table(agg: dict, sets: list[str], conditions: list[str], items: dict[str, int]) -> str:
    """Markdown: a row per test set (its frames) and group, a column per condition and paired
    difference; cells mean ± std over seeds (IoU points)."""
    diff, adapt = bool(agg["within_minus_resize"]), list(agg["adapt_minus_within"])
    header = (["test set", "frames"] + conditions + (["within − resize"] if diff else [])
              + [f"{c} − within" for c in adapt])
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for s in sets + [g for g in agg["groups"] if agg["groups"][g]]:
        row = [s if s in sets else f"**{s}** (mean)", str(items.get(s, "")) if s in sets else ""]
        row += [format_stat(agg["cells"][s][c]) for c in conditions]
        if diff:
            row.append(format_stat(agg["within_minus_resize"].get(s), signed=True))
        for c in adapt:
            row.append(format_stat(agg["adapt_minus_within"][c].get(s), signed=True))
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"


def bar_plot(cell: dict[tuple[str, str], float], groups: list[str], conditions: list[str], title: str,
             spread: dict[tuple[str, str], float] | None = None) -> np.ndarray:
    """Grouped bars: road IoU in [0, 1] per group and condition (colours); ``spread``: error bars
    (+/- that much) where given."""
    colours = [(160, 160, 160), (200, 140, 60), (60, 170, 60), (40, 110, 30), (60, 60, 200), (170, 70, 170),
               (0, 150, 255)]
    W, H, top, bottom, left = 1000, 540, 80, 60, 60
    img = np.full((H, W, 3), 255, np.uint8)
    gw = (W - left - 20) / len(groups)
    bw = gw * 0.8 / len(conditions)
    y0 = H - bottom
    for t in range(0, 101, 20):
        y = int(y0 - t / 100 * (H - top - bottom))
        cv2.line(img, (left, y), (W - 20, y), (225, 225, 225), 1)
        cv2.putText(img, f"{t}", (18, y + 5), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (80, 80, 80), 1, cv2.LINE_AA)
    for g, name in enumerate(groups):
        x0 = left + g * gw + gw * 0.1
        for j, c in enumerate(conditions):
            if (name, c) not in cell:
                continue
            h = cell[name, c] * (H - top - bottom)
            x = int(x0 + j * bw)
            cv2.rectangle(img, (x, int(y0 - h)), (int(x + bw - 2), y0), colours[j % len(colours)], -1)
            e = (spread or {}).get((name, c)) or 0.0
            if e:
                e *= H - top - bottom
                xm = int(x + bw / 2 - 1)
                for a, b in (((xm, int(y0 - h - e)), (xm, int(y0 - h + e))), ((xm - 3, int(y0 - h - e)),
                             (xm + 3, int(y0 - h - e))), ((xm - 3, int(y0 - h + e)), (xm + 3, int(y0 - h + e)))):
                    cv2.line(img, a, b, (0, 0, 0), 1)
            cv2.putText(img, f"{100 * cell[name, c]:.0f}", (x, int(y0 - h - e) - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.35,
                        (40, 40, 40), 1, cv2.LINE_AA)
        cv2.putText(img, name, (int(x0), y0 + 22), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    for j, c in enumerate(conditions):
        x = left + j * 150
        cv2.rectangle(img, (x, 18), (x + 14, 32), colours[j % len(colours)], -1)
        cv2.putText(img, c, (x + 20, 31), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(img, title, (left, 52), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (80, 80, 80), 1, cv2.LINE_AA)
    return img
