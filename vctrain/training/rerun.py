"""Runs never lost (issues 72, 80): what ``vctrain fit`` does when its ``--out`` is already there.

A checkpoint records the run's ``request``: its settings as asked (before the recipe fills them; less
:data:`vctrain.training.config.RUN_ONLY`), a stamp of its data (:func:`data_stamp`) and what the stamp
was made of (:func:`data_files`: each data folder's files, so a change can be named). The same command
again (:func:`rerun_plan`):

* on an interrupted run (``OUT.last.pt`` of the same request, epochs to go): resumes it from there --
  the epochs' order and augmentation depend on (seed, epoch) only, so the result is the uninterrupted
  run's, and the log is rewritten from the checkpoint's history (no row twice);
* on a finished run of the same request: says so and trains nothing (exit 0), so a Makefile that
  reruns it still works;
* on a run of the same settings whose frames, labels or stores changed since (another stamp): keeps
  the model there, its log and ``.last.pt`` beside it under the first free name ``OUT-stem.old<N>.pt``
  (:func:`keep_aside`), says what changed and that name, and trains afresh (issue 80: a warp into the
  wrong store had silently replaced a 20-epoch model). Not a refusal: an edited label must still redo
  what depends on it in a Makefile, and no finished model is lost;
* on a model of another run (other settings, or a file fit did not write): refuses, with the fix
  (``--overwrite``, ``--resume``, another ``--out``), naming the settings as given (a setting left out
  as the default it took, never ``None``).
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Any

from vcprep.errors import InputError, VCError

from .config import DEFAULT_RECIPE, RECIPES, RUN_ONLY, TrainConfig

__all__ = ["request_of", "data_files", "data_stamp", "data_change", "keep_aside", "log_path", "rerun_plan",
           "interrupted_after"]

DATA_KEYS = ("data_stamp", "data_files")  # what a request records of its data, not of its settings
# settings added after requests were first recorded, and the value that trains as before: left out of a request
# at that value, so the same command finds the runs of an older vctrain the same
REQUEST_ADDED = {"outputs": "road", "keep_aspect": False}
_ALWAYS = object()  # (a setting not in REQUEST_ADDED is always recorded)


def _data_folders(cfg: TrainConfig) -> list[tuple[str, str]]:
    """(role, folder) of every data folder a run reads, as a user names them."""
    roles = [("frames", cfg.images), ("labels", cfg.labels), *(("store", s) for s in cfg.stores),
             *(("validation store", s) for s in cfg.val_stores), ("validation frames", cfg.val_images),
             ("validation labels", cfg.val_labels)]
    return [(role, str(top)) for role, top in roles if top]


def data_files(cfg: TrainConfig) -> dict[str, dict[str, str]]:
    """{folder: {file path within it: 'size:mtime_ns'}} of every file under the run's data folders
    (``--images``, ``--labels``, the stores, the validation stores and frames); a missing folder is empty."""
    out: dict[str, dict[str, str]] = {}
    for _, top in _data_folders(cfg):
        files = out.setdefault(top, {})
        if not Path(top).exists():
            continue
        for root, dirs, names in os.walk(top, followlinks=True):
            dirs.sort()
            for name in sorted(names):
                p = Path(root) / name
                try:
                    st = p.stat()
                except OSError:
                    continue
                files[str(p.relative_to(top))] = f"{st.st_size}:{st.st_mtime_ns}"
    return out


def data_stamp(cfg: TrainConfig, files: dict[str, dict[str, str]] | None = None) -> str:
    """A hash of the names, sizes and modification times of every file under the run's data folders
    (:func:`data_files`): changed frames or labels change it."""
    h = hashlib.sha256()
    for _, top in _data_folders(cfg):
        for rel, stat in (files if files is not None else data_files(cfg)).get(top, {}).items():
            size, mtime = stat.split(":")
            h.update(f"{rel}\0{size}\0{mtime}\n".encode())
    return h.hexdigest()[:16]


def request_of(cfg: TrainConfig) -> dict[str, Any]:
    """The run as asked: every setting but how it runs (RUN_ONLY), plus its data stamp and files."""
    files = data_files(cfg)
    asked = {k: v for k, v in cfg.to_dict().items() if k not in RUN_ONLY and REQUEST_ADDED.get(k, _ALWAYS) != v}
    return {**asked, "data_stamp": data_stamp(cfg, files), "data_files": files}


def _kind(role: str, rel: str) -> str | None:
    """What a file of a data folder is, in a user's words: a store's images/ are frames, labels/ labels,
    its manifest and parameters its records; None for what follows from them (valid masks, the lock)."""
    if not role.endswith("store"):
        return role.rsplit(" ", 1)[-1]
    top = rel.split(os.sep, 1)[0]
    if top in ("valid", "store.lock"):
        return None
    return {"images": "frames", "labels": "labels"}.get(top, "records")


def data_change(cfg: TrainConfig, theirs: dict[str, Any], ours: dict[str, Any]) -> str:
    """What changed in the run's data between two requests, e.g. 'store stores/mine: 49 frames added,
    49 labels added'; the stamp's words where the older request did not record its files."""
    old, new = theirs.get("data_files"), ours.get("data_files") or {}
    if old is None:
        return "the frames or labels changed"
    said = []
    for role, top in _data_folders(cfg):
        a, b = old.get(top, {}), new.get(top, {})
        counts: dict[str | None, list[int]] = {}
        for rel in set(a) | set(b):
            if a.get(rel) != b.get(rel):
                c = counts.setdefault(_kind(role, rel), [0, 0, 0])
                c[0 if rel not in a else 1 if rel not in b else 2] += 1
        named = sorted((kind, c) for kind, c in counts.items() if kind not in (None, "records"))
        parts = [f"{n} {kind if n != 1 else kind[:-1]} {what}" for kind, c in named
                 for n, what in zip(c, ("added", "removed", "changed")) if n]
        if not parts and counts.get("records"):
            parts = ["its records changed"]
        if parts:
            said.append(f"{role} {top}: {', '.join(parts)}")
    return "; ".join(said) or "the frames or labels changed"


def log_path(cfg: TrainConfig) -> Path:
    """The run's JSON-lines log: ``cfg.log``, else beside OUT (runs/vc.pt -> runs/vc.log.jsonl)."""
    out = Path(cfg.out)
    return Path(cfg.log) if cfg.log else out.with_name(out.stem + ".log.jsonl")


def keep_aside(cfg: TrainConfig) -> tuple[Path, Path]:
    """Move the model at OUT, its ``.last.pt`` and its log to the first free ``OUT-stem.old<N>`` names
    beside them (runs/vc.pt -> runs/vc.old1.pt, runs/vc.old1.last.pt, runs/vc.old1.log.jsonl; a log
    given by --log: its own stem .old<N>); returns (the model's new path, the log's)."""
    from .checkpoint import last_path

    out, log = Path(cfg.out), log_path(cfg)
    n = 1
    while True:
        kept = out.with_name(f"{out.stem}.old{n}{out.suffix}")
        kept_log = kept.with_name(kept.stem + ".log.jsonl") if not cfg.log else \
            log.with_name(f"{log.stem}.old{n}{log.suffix}")
        moves = [(out, kept), (last_path(out), last_path(kept)), (log, kept_log)]
        if not any(dst.exists() for _, dst in moves):
            break
        n += 1
    for src, dst in moves:
        if src.is_file():
            os.replace(src, dst)
    return kept, kept_log


def _shown(k: str, v: Any, resolved: Any) -> str:
    """A setting as a user gave it; one left out as the default it took (``resolved``), never None."""
    if v is None:
        return f"{_shown(k, resolved, None)} (the default)" if resolved is not None else "not given"
    if isinstance(v, (list, tuple)):
        return " ".join(str(x) for x in v) if v else "none"
    return str(v)


def _differences(cfg: TrainConfig, ours: dict[str, Any], theirs: dict[str, Any], their_config: dict[str, Any]) -> str:
    """'epochs 20 (the default) -> 5, ...': the settings that differ, as given then and now."""
    recipe = RECIPES.get(cfg.recipe or DEFAULT_RECIPE, {})
    keys = [k for k in sorted(set(ours) | set(theirs)) if k not in DATA_KEYS and ours.get(k) != theirs.get(k)]
    return ", ".join(f"{k.replace('_', '-')} {_shown(k, theirs.get(k), their_config.get(k))} -> "
                     f"{_shown(k, ours.get(k), recipe.get(k))}" for k in keys[:4]) or "its data"


def rerun_plan(cfg: TrainConfig, overwrite: bool) -> tuple[str, str | None]:
    """What the command does with OUT: ('train', note) -- afresh, or resuming (``cfg.resume`` set) --,
    ('aside', note): afresh, the model of the same settings on other data moved aside first
    (:func:`keep_aside`; the note names where), or ('done', note): the same run finished, nothing to train. Raises :class:`InputError` when OUT is another run's and ``overwrite``
    is not given. With ``overwrite`` the old OUT.last.pt goes."""
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
        if {k: v for k, v in theirs.items() if k not in DATA_KEYS} != {k: v for k, v in ours.items() if k not in DATA_KEYS}:
            raise InputError(f"a model of another run is there ({_differences(cfg, ours, theirs, ck.get('config') or {})})",
                             path, fix)
        if theirs.get("data_stamp") != ours["data_stamp"]:
            if int(os.environ.get("RANK", 0)) != 0:  # torchrun: rank 0 alone moves the files
                return "train", None
            change = data_change(cfg, theirs, ours)
            kept, kept_log = keep_aside(cfg)
            return "aside", (f"{out}: {change} since it was trained: that model is kept as {kept} (its log "
                             f"{kept_log}); training afresh")
        epochs = int(ck["config"]["epochs"])
        if int(ck["epoch"]) >= epochs:
            return "done", f"{out}: this run is finished ({epochs} epochs, the same settings and data): nothing to do " \
                           f"(--overwrite trains it again)"
        if path == last:
            cfg.resume = str(last)
            return "train", f"{out}: resuming the interrupted run after epoch {ck['epoch']} of {epochs} ({last})"
        return "train", None  # OUT alone, of this run before its first epoch: afresh
    return "train", None


def interrupted_after(cfg: TrainConfig) -> int | None:
    """The epoch after which a training of ``cfg`` stopped unfinished: its ``.last.pt`` beside ``cfg.out``
    holds the very request (settings and data, :func:`request_of`) and fewer epochs than asked; None
    otherwise (no such file, another run's, unreadable, or finished). A study's quiet form of
    :func:`rerun_plan`'s resume, which refuses another run's files instead of passing them by."""
    from .checkpoint import last_path, load_checkpoint

    last = last_path(Path(cfg.out))
    if not last.is_file():
        return None
    try:
        ck = load_checkpoint(last)
    except VCError:
        return None
    if ck.get("request") != request_of(cfg) or int(ck["epoch"]) >= int(ck["config"]["epochs"]):
        return None
    return int(ck["epoch"])
