"""A model's outputs: one per label definition (:data:`vcprep.labels.DEFINITIONS`), and the loss that lets each
dataset supervise only the output it labels.

Datasets disagree about what road is: CamVid, Cityscapes, KITTI and LUMS label the carriageway (*road*),
IDD and BDD100K the *drivable* area (IDD's with parking and dirt shoulders). A model has the outputs
:data:`ONE_OUTPUT` (two classes, softmax class 1 = P(road): every model trained before this, and every model
trained without ``outputs``) or :data:`TWO_OUTPUTS` (three classes, :data:`CLASSES`: 0 not drivable, 1 drivable
but not road, 2 road; P(road) = p2, P(drivable) = p1 + p2, so drivable always holds road).

Targets of a two-output run are one integer tensor of set codes (:func:`encode`): an item's label (0, 1, 255)
plus 2 where its format's definition is drivable, so that a road label 1 is code 1 = the class set {2}, 0 is
code 0 = {0, 1}; a drivable label 1 is code 3 = {1, 2}, 0 is code 2 = {0}; 255 stays ignored
(:data:`CLASS_SETS`). The set-valued cross entropy (:func:`set_cross_entropy`) is, over the labelled pixels,
the mean of ``logsumexp(all logits) - logsumexp(logits in the pixel's set)``: minus the log of the set's
probability. A one-output run keeps ``F.cross_entropy`` on its 0/1 labels, as before. No torch at import.
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from vcprep.errors import InputError
from vcprep.labels import DEFINITIONS, IGNORE

__all__ = ["ONE_OUTPUT", "TWO_OUTPUTS", "OUTPUT_CHOICES", "CLASSES", "CLASS_SETS", "DEFINITION_OFFSET",
           "parse_outputs", "num_classes", "outputs_of", "check_output", "encode", "set_cross_entropy",
           "output_probability", "output_probability_np", "decoded", "loss_of", "scored"]

ONE_OUTPUT = ("road",)
TWO_OUTPUTS = tuple(DEFINITIONS)  # ('road', 'drivable')
OUTPUT_CHOICES = {",".join(o): o for o in (ONE_OUTPUT, TWO_OUTPUTS)}  # TrainConfig.outputs / --outputs values
CLASSES = ("not drivable", "drivable, not road", "road")  # a two-output network's classes
# a label definition -> what its code is offset by (encode); code -> the classes it allows (a row of CLASS_SETS)
DEFINITION_OFFSET = {"road": 0, "drivable": 2}
CLASS_SETS = ((True, True, False),   # 0: road definition, not road -> {0, 1}
              (False, False, True),  # 1: road definition, road -> {2}
              (True, False, False),  # 2: drivable definition, not drivable -> {0}
              (False, True, True))   # 3: drivable definition, drivable -> {1, 2}


def parse_outputs(spec: str | Sequence[str] | None) -> tuple[str, ...]:
    """``'road'`` or ``'road,drivable'`` (a list of the names too; None: road) -> the outputs tuple."""
    if spec is None:
        return ONE_OUTPUT
    key = spec if isinstance(spec, str) else ",".join(spec)
    key = ",".join(p.strip() for p in key.split(","))
    if key not in OUTPUT_CHOICES:
        raise InputError(f"unknown outputs '{key}'", None, f"use {' or '.join(OUTPUT_CHOICES)}")
    return OUTPUT_CHOICES[key]


def num_classes(outputs: Sequence[str]) -> int:
    """The network's classes for ``outputs``: 2 for road alone, 3 for road and drivable."""
    return 2 if tuple(outputs) == ONE_OUTPUT else len(CLASSES)


def outputs_of(data: Mapping[str, Any] | None) -> tuple[str, ...]:
    """The outputs a checkpoint's ``data`` section records (a model trained before them: road alone)."""
    return tuple((data or {}).get("outputs") or ONE_OUTPUT)


def check_output(output: str, outputs: Sequence[str], path: Any = None) -> str:
    """``output`` if the model of ``outputs`` has it; else one line naming what it has and the fix."""
    if output not in DEFINITIONS:
        raise InputError(f"unknown output '{output}'", path, f"use --output {' or '.join(DEFINITIONS)}")
    if output not in outputs:
        raise InputError(f"model has the output{'s' if len(outputs) > 1 else ''} {', '.join(outputs)}, not "
                         f"'{output}'", path, f"use --output {outputs[0]}, or a model trained with --outputs "
                         f"{','.join(TWO_OUTPUTS)}")
    return output


def encode(label: np.ndarray, definition: str) -> np.ndarray:
    """A decoded label (0, 1, 255) of a format whose road means ``definition`` -> its set codes (module
    docstring): the label plus :data:`DEFINITION_OFFSET`, 255 kept."""
    offset = DEFINITION_OFFSET[definition]
    if not offset:
        return label
    return np.where(label == IGNORE, label, label + offset).astype(label.dtype)


def decoded(codes):
    """(labels 0/1/255, whether each pixel's definition is drivable) of set codes (numpy or torch)."""
    labelled = codes != IGNORE
    drivable = labelled & (codes >= 2)
    return codes - 2 * drivable, drivable


def set_cross_entropy(logits, codes):
    """The set-valued cross entropy of ``logits`` (N, 3, h, w) against set ``codes`` (N, h, w; module
    docstring): the mean over labelled pixels of logsumexp(all logits) - logsumexp(logits in the set);
    NaN where no pixel is labelled (as ``F.cross_entropy`` with every pixel ignored)."""
    import torch

    codes = codes.long()
    labelled = codes != IGNORE
    sets = torch.tensor(CLASS_SETS, dtype=torch.bool, device=logits.device)[codes.clamp(0, len(CLASS_SETS) - 1)]
    sets = sets.permute(0, 3, 1, 2)  # (N, 3, h, w)
    inside = torch.logsumexp(logits.masked_fill(~sets, float("-inf")), dim=1)
    per_pixel = torch.logsumexp(logits, dim=1) - inside
    return per_pixel[labelled].sum() / labelled.sum()


def output_probability(logits, output: str, dim: int = 1):
    """P(``output``) of logits (torch) along ``dim``: two classes -> softmax class 1 (road); three ->
    road = softmax class 2, drivable = class 1 + class 2 (never below road's, float rounding included)."""
    import torch

    p = torch.softmax(logits, dim=dim)
    if logits.shape[dim] == 2:
        return p.select(dim, 1)
    return p.select(dim, 2) if output == "road" else p.select(dim, 1) + p.select(dim, 2)


def output_probability_np(logits: np.ndarray, output: str) -> np.ndarray:
    """:func:`output_probability` of logits (K, h, w) in numpy (float32 (h, w))."""
    e = np.exp(logits - logits.max(axis=0, keepdims=True))
    s = e.sum(axis=0)
    if logits.shape[0] == 2:
        return (e[1] / s).astype(np.float32)
    return ((e[2] if output == "road" else e[1] + e[2]) / s).astype(np.float32)


def loss_of(logits, y, weight=None):
    """The training loss: cross-entropy over two classes (labels 0/1, 255 ignored), or over three the
    set-valued cross entropy of the targets' set codes (:func:`vctrain.training.outputs.set_cross_entropy`)."""
    from torch.nn import functional as F

    if logits.shape[1] == 2:
        return F.cross_entropy(logits, y, weight=weight, ignore_index=255)
    return set_cross_entropy(logits, y)


def scored(logits, y) -> tuple[np.ndarray, np.ndarray]:
    """(prediction, labels 0/1/255) of a batch as the road metrics take them: two classes the argmax;
    three each pixel on its definition's output (argmax class 2 against the rest for road, classes 1 and 2
    against 0 for drivable) and its set codes back to labels."""
    import torch

    if logits.shape[1] == 2:
        return logits.argmax(1).cpu().numpy(), y.cpu().numpy().astype(np.uint8)
    label, drivable = decoded(y)
    l0, l1, l2 = logits.unbind(1)
    road = l2 > torch.logaddexp(l0, l1)
    pred = torch.where(drivable, torch.logaddexp(l1, l2) > l0, road)
    return pred.cpu().numpy(), label.cpu().numpy().astype(np.uint8)
