"""Road segmentation metrics.

Binary road masks against labels (0 not road, 1 road, 255 ignore; ignore pixels never count):

- ``iou`` (dataset road IoU, the paper's figure) = ΣTP / Σ(TP + FP + FN) over all images;
- ``mean_image_iou`` = mean over images of TP / (TP + FP + FN); images with no road in either
  the label or the prediction (union 0) are left out of the mean;
- ``precision`` = ΣTP / Σ(TP + FP), ``recall`` = ΣTP / Σ(TP + FN), ``f1`` = their harmonic mean
  (0 where undefined).

KITTI road benchmark metrics (Fritsch et al. 2013; devkit ``helper.py``) from road probability
maps quantised to 8 bits, p in 0..255: for every threshold t = k / 255, k = 0..255, a pixel is road
iff p >= k; TP/FP/FN/TN are summed over the dataset per threshold; thresholds where precision and
recall are both 0 are dropped; ``maxf`` = max F1 over thresholds; ``ap`` = Pascal-VOC 11-point
average precision (mean over r in 0, 0.1, ..., 1 of the max precision at recall >= r, 0 where no
threshold reaches r); ``precision``, ``recall``, ``fpr`` = FP / (FP + TN), ``fnr`` = FN / (FN + TP)
at the MaxF threshold, reported as ``threshold`` in [0, 1].
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from vcprep.errors import InputError

__all__ = ["confusion", "RoadMetrics", "KittiMetrics", "road_metrics", "kitti_metrics"]

IGNORE = 255


def _check(pred: np.ndarray, label: np.ndarray, what: str = "prediction") -> None:
    if pred.shape != label.shape:
        raise InputError(f"{what} is {pred.shape[::-1]} but the label is {label.shape[::-1]} (w x h)", None,
                         "predict at the label's image size")


def confusion(pred: np.ndarray, label: np.ndarray) -> tuple[int, int, int, int]:
    """(TP, FP, FN, TN) of a road mask ``pred`` (bool or 0/1, any nonzero = road) against ``label``."""
    _check(pred, label)
    valid = label != IGNORE
    p = (pred != 0) & valid
    g = (label == 1) & valid
    tp = int(np.count_nonzero(p & g))
    fp = int(np.count_nonzero(p & ~g))
    fn = int(np.count_nonzero(~p & g))
    tn = int(np.count_nonzero(valid)) - tp - fp - fn
    return tp, fp, fn, tn


def _div(a: float, b: float) -> float:
    return float(a) / float(b) if b else 0.0


@dataclass
class RoadMetrics:
    """Accumulates binary-mask counts image by image; :meth:`result` gives the summary dict."""

    tp: int = 0
    fp: int = 0
    fn: int = 0
    tn: int = 0
    image_ious: list[float] = field(default_factory=list)

    def add(self, pred: np.ndarray, label: np.ndarray) -> None:
        tp, fp, fn, tn = confusion(pred, label)
        self.add_counts(tp, fp, fn, tn)

    def add_counts(self, tp: int, fp: int, fn: int, tn: int) -> None:
        self.tp += tp
        self.fp += fp
        self.fn += fn
        self.tn += tn
        if tp + fp + fn:
            self.image_ious.append(tp / (tp + fp + fn))

    def result(self) -> dict[str, float]:
        p = _div(self.tp, self.tp + self.fp)
        r = _div(self.tp, self.tp + self.fn)
        return {
            "iou": _div(self.tp, self.tp + self.fp + self.fn),
            "mean_image_iou": float(np.mean(self.image_ious)) if self.image_ious else 0.0,
            "precision": p,
            "recall": r,
            "f1": _div(2 * p * r, p + r),
        }


def road_metrics(preds, labels) -> dict[str, float]:
    """:class:`RoadMetrics` over paired iterables of masks and labels."""
    m = RoadMetrics()
    for p, g in zip(preds, labels):
        m.add(p, g)
    return m.result()


@dataclass
class KittiMetrics:
    """Accumulates per-threshold counts from 8-bit road probability maps (see module docstring)."""

    pos_hist: np.ndarray = field(default_factory=lambda: np.zeros(256, dtype=np.int64))
    neg_hist: np.ndarray = field(default_factory=lambda: np.zeros(256, dtype=np.int64))

    def add(self, prob: np.ndarray, label: np.ndarray) -> None:
        """``prob`` uint8 (0..255 = road probability), ``label`` 0/1/255."""
        _check(prob, label, "probability map")
        if prob.dtype != np.uint8:
            raise InputError(f"probability map has type {prob.dtype}", None, "give 8-bit probability maps (0-255)")
        valid = label != IGNORE
        self.pos_hist += np.bincount(prob[valid & (label == 1)], minlength=256)
        self.neg_hist += np.bincount(prob[valid & (label != 1)], minlength=256)

    def result(self) -> dict[str, float]:
        pos_num = int(self.pos_hist.sum())
        neg_num = int(self.neg_hist.sum())
        # threshold k: road iff p >= k  ->  TP(k) = #pos with p >= k, FP(k) = #neg with p >= k
        tp = np.cumsum(self.pos_hist[::-1])[::-1].astype(np.float64)
        fp = np.cumsum(self.neg_hist[::-1])[::-1].astype(np.float64)
        fn = pos_num - tp
        tn = neg_num - fp
        recall = tp / pos_num if pos_num else np.zeros(256)
        precision = tp / np.maximum(tp + fp, 1e-300)
        keep = ~((recall == 0) & (precision == 0))
        if not keep.any():
            return {"maxf": 0.0, "ap": 0.0, "precision": 0.0, "recall": 0.0, "fpr": _div(fp[0], neg_num),
                    "fnr": 1.0 if pos_num else 0.0, "threshold": 0.0}
        k = np.flatnonzero(keep)
        P, R = precision[k], recall[k]
        ap = 0.0
        for r in np.linspace(0.0, 1.0, 11):
            sel = R >= r - 1e-12
            ap += float(P[sel].max()) if sel.any() else 0.0
        ap /= 11
        F = 2 * P * R / np.maximum(P + R, 1e-300)
        best = int(np.argmax(F))
        i = int(k[best])
        return {
            "maxf": float(F[best]),
            "ap": ap,
            "precision": float(P[best]),
            "recall": float(R[best]),
            "fpr": _div(fp[i], fp[i] + tn[i]),
            "fnr": _div(fn[i], fn[i] + tp[i]),
            "threshold": i / 255.0,
        }


def kitti_metrics(probs, labels) -> dict[str, float]:
    """:class:`KittiMetrics` over paired iterables of uint8 probability maps and labels."""
    m = KittiMetrics()
    for p, g in zip(probs, labels):
        m.add(p, g)
    return m.result()
