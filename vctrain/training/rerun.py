"""Runs never lost (issue 72): what ``vctrain fit`` does when its ``--out`` is already there.

A checkpoint records the run's ``request``: its settings as asked (before the recipe fills them; less
:data:`vctrain.training.config.RUN_ONLY`) and a stamp of its data (:func:`data_stamp`). The same
command again (:func:`rerun_plan`):

* on an interrupted run (``OUT.last.pt`` of the same request, epochs to go): resumes it from there --
  the epochs' order and augmentation depend on (seed, epoch) only, so the result is the uninterrupted
  run's, and the log is rewritten from the checkpoint's history (no row twice);
* on a finished run of the same request: says so and trains nothing (exit 0), so a Makefile that
  reruns it still works; frames or labels changed since (another stamp): trains it again;
* on a model of another run (other settings, or a file fit did not write): refuses, with the fix
  (``--overwrite``, ``--resume``, another ``--out``).
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Any

from vcprep.errors import InputError, VCError

from .config import RUN_ONLY, TrainConfig

__all__ = ["request_of", "data_stamp", "rerun_plan"]


def data_stamp(cfg: TrainConfig) -> str:
    """A hash of the names, sizes and modification times of every file under the run's data folders
    (``--images``, ``--labels``, the stores, the validation stores and frames): changed frames or labels change it."""
    h = hashlib.sha256()
    for top in [cfg.images, cfg.labels, *cfg.stores, *cfg.val_stores, cfg.val_images, cfg.val_labels]:
        if not top or not Path(top).exists():
            continue
        for root, dirs, files in os.walk(top, followlinks=True):
            dirs.sort()
            for name in sorted(files):
                p = Path(root) / name
                try:
                    st = p.stat()
                except OSError:
                    continue
                h.update(f"{p.relative_to(top)}\0{st.st_size}\0{st.st_mtime_ns}\n".encode())
    return h.hexdigest()[:16]


def request_of(cfg: TrainConfig) -> dict[str, Any]:
    """The run as asked: every setting but how it runs (RUN_ONLY), plus its data stamp."""
    return {**{k: v for k, v in cfg.to_dict().items() if k not in RUN_ONLY}, "data_stamp": data_stamp(cfg)}


def _differences(ours: dict[str, Any], theirs: dict[str, Any]) -> str:
    keys = [k for k in sorted(set(ours) | set(theirs)) if k != "data_stamp" and ours.get(k) != theirs.get(k)]
    return ", ".join(f"{k.replace('_', '-')} {theirs.get(k)} -> {ours.get(k)}" for k in keys[:4]) or "its data"


def rerun_plan(cfg: TrainConfig, overwrite: bool) -> tuple[str, str | None]:
    """What the command does with OUT: ('train', note) -- afresh, or resuming (``cfg.resume`` set) --
    or ('done', note): the same run finished, nothing to train. Raises :class:`InputError` when OUT
    is another run's and ``overwrite`` is not given. With ``overwrite`` the old OUT.last.pt goes."""
    from .checkpoint import last_path, load_checkpoint

    out = Path(cfg.out)
    last = last_path(out)
    if cfg.resume is not None:
        return "train", None
    if overwrite:
        last.unlink(missing_ok=True)
        return "train", None
    ours = request_of(cfg)
    fix = f"add --overwrite to replace it, --resume {last} to continue it, or give another --out"
    for path in (last, out):
        if not path.is_file():
            continue
        try:
            ck = load_checkpoint(path)
        except VCError:
            raise InputError("a file that is not a model of vctrain fit is there", path,
                             "add --overwrite to replace it, or give another --out") from None
        theirs = ck.get("request")
        if theirs is None:
            raise InputError("a model of another run is there (of an older vctrain, or written by hand)", path, fix)
        same = {k: v for k, v in theirs.items() if k != "data_stamp"} == \
            {k: v for k, v in ours.items() if k != "data_stamp"}
        if not same:
            raise InputError(f"a model of another run is there ({_differences(ours, theirs)})", path, fix)
        if theirs.get("data_stamp") != ours["data_stamp"]:
            last.unlink(missing_ok=True)
            return "train", f"{out}: the frames or labels changed since it was trained: training it again"
        epochs = int(ck["config"]["epochs"])
        if int(ck["epoch"]) >= epochs:
            return "done", f"{out}: this run is finished ({epochs} epochs, the same settings and data): nothing to do " \
                           f"(--overwrite trains it again)"
        if path == last:
            cfg.resume = str(last)
            return "train", f"{out}: resuming the interrupted run after epoch {ck['epoch']} of {epochs} ({last})"
        return "train", None  # OUT alone, of this run before its first epoch: afresh
    return "train", None
