"""Training sets whose items come in parts of different input sizes, a batch always one part's:

- :class:`MixedViews` (``baseline: mixed``, issue 53's candidate): every frame twice, its virtual-camera
  store item and its original image resized, each view at its own working size and window;
- :class:`AspectParts` (``keep_aspect``, issue 82's pixel budget of wide frames): a resize baseline's
  frames grouped by their working size, every frame at the run's pixel count at its own aspect
  (:func:`resize_working_size`), so a 1242x375 KITTI frame is not squashed to a 4:3 canvas.

:func:`view_batches` cuts an epoch's order into batches of one part each.
"""
from __future__ import annotations

import bisect
import math
from typing import Any, Callable, Sequence

import torch

from vcprep.io import image_size

from .data import RoadDataset, Sample

__all__ = ["Parts", "MixedViews", "AspectParts", "resize_working_size", "view_batches"]


def resize_working_size(store_size: tuple[int, int], frame_size: tuple[int, int]) -> tuple[int, int]:
    """The resize baseline's working size (w, h): the virtual store's pixel count at the aspect of the
    frames (``frame_size``, w, h), so the twin gets the same pixel budget and no frame is squashed
    (``vctrain fit STORE --baseline resize`` without --size, and a study's resize twin)."""
    n = store_size[0] * store_size[1]
    w0, h0 = frame_size
    return max(32, int(round(math.sqrt(n * w0 / h0)))), max(32, int(round(math.sqrt(n * h0 / w0))))


class Parts(torch.utils.data.Dataset):
    """Items of several :class:`RoadDataset` parts, each at its own working size: item ``i`` of the
    whole is item ``i - start`` of the part it falls in (the parts' items in order)."""

    def __init__(self, *parts: RoadDataset):
        self.parts = tuple(parts)
        self.samples: list[Sample] = [s for p in self.parts for s in p.samples]
        self._starts, n = [], 0
        for p in self.parts:
            self._starts.append(n)
            n += len(p)

    def __len__(self) -> int:
        return len(self.samples)

    def view(self, i: int) -> int:
        """The part item ``i`` is in."""
        return bisect.bisect_right(self._starts, i) - 1  # (the last part starting at or before i)

    def _part(self, i: int) -> tuple[RoadDataset, int]:
        k = self.view(i)
        return self.parts[k], i - self._starts[k]

    def item(self, i: int):
        ds, j = self._part(i)
        return ds.item(j)

    def __getitem__(self, i: int):
        ds, j = self._part(i)
        return ds[j]


class MixedViews(Parts):
    """Mixed-view training (issue 53's candidate): every frame twice, its virtual-camera store item
    (view 0) and its original image simply resized (view 1), each view at its own working size and
    training window; items ``[0, len(virtual))`` are view 0, the rest view 1. Batches hold one view
    (:func:`view_batches`), so each keeps its own input size. At test time the model's two views'
    probabilities are averaged in the camera's own pixels (:class:`vctrain.predict.Predictor`)."""

    def __init__(self, virtual: RoadDataset, resized: RoadDataset):
        super().__init__(virtual, resized)
        self.n_virtual = len(virtual)


class AspectParts(Parts):
    """A resize baseline's frames at their own aspect (``keep_aspect``): the samples grouped by
    their working size under the pixel budget ``budget`` (w, h) (:func:`resize_working_size` of each frame's
    size), one :class:`RoadDataset` per size made by ``make(samples, size)``, the groups in the order
    their first sample comes (so one size of frames is the samples in their order)."""

    def __init__(self, samples: Sequence[Sample], budget: tuple[int, int],
                 make: Callable[[list[Sample], tuple[int, int]], RoadDataset]):
        groups: dict[tuple[int, int], list[Sample]] = {}
        sizes: dict[Any, tuple[int, int]] = {}
        for s in samples:
            if s.image not in sizes:
                sizes[s.image] = resize_working_size(budget, image_size(s.image))
            groups.setdefault(sizes[s.image], []).append(s)
        super().__init__(*(make(g, size) for size, g in groups.items()))
        self.sizes = list(groups)


def view_batches(dataset: Any, order: Sequence[int], batch: int) -> list[list[int]]:
    """``order`` cut into batches of ``batch`` items; for :class:`Parts` every batch holds one part
    (items join their part's open batch in ``order``'s order; a batch is emitted when full, then the
    open ones in the parts' order), so the order's randomness carries over to the batches."""
    if not isinstance(dataset, Parts):
        return [list(order[k:k + batch]) for k in range(0, len(order), batch)]
    out: list[list[int]] = []
    pending: dict[int, list[int]] = {k: [] for k in range(len(dataset.parts))}
    for i in order:
        b = pending[dataset.view(i)]
        b.append(i)
        if len(b) == batch:
            out.append(list(b))
            b.clear()
    out += [b for b in pending.values() if b]
    return out
