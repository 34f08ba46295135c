"""A study's run plan and its records: which models are trained on what and scored where
(:func:`plan_runs`), and the result files of finished work (:func:`pending`, :func:`write_result`).

* each dataset of role ``both`` is held out in turn: trained on every other dataset that may be
  trained on (role ``train`` or ``both``), tested on the held-out one (``runs/<heldout>/<condition>/``);
* with datasets of role ``test`` (never trained on), one more model per condition is trained on
  ALL trainable datasets and tested on every test-role dataset (``runs/_all/<condition>/``,
  ``result-<dataset>.json`` per test-role dataset).
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

from ..report import write_json
from .spec import Dataset, Study

__all__ = ["ALL_RUN", "Run", "plan_runs", "pending", "write_result", "what"]

ALL_RUN = "_all"  # runs/_all/<condition>/: trained on every trainable dataset, scored on the test-role ones
INFO = ("train_datasets", "train_items", "val_items", "best_epoch", "best_val_iou", "epochs", "input_size",
        "train_seconds", "train_images_per_s")  # what each result row repeats of its model's training


@dataclass(frozen=True)
class Run:
    """One model: ``condition`` trained on ``train``, scored on each dataset of ``tests``."""

    name: str                   # runs/<name>/<condition>/: the held-out dataset, or ALL_RUN
    condition: str
    train: tuple[Dataset, ...]
    tests: tuple[Dataset, ...]

    def folder(self, out: Path) -> Path:
        """``OUT/runs/<name>/<condition>/``: the run's model, logs and results."""
        return out / "runs" / self.name / self.condition

    def result_file(self, run_dir: Path, ds: Dataset) -> Path:
        return run_dir / ("result.json" if ds.name == self.name else f"result-{ds.name}.json")


def plan_runs(study: Study, conditions: Sequence[str], evaluated: Sequence[str]) -> list[Run]:
    """Leave-one-out runs for the evaluated 'both' datasets, then (with test-role datasets) one run
    per condition on every trainable dataset, scored on each evaluated test-role dataset."""
    trainable = tuple(d for d in study.datasets if d.trained)
    chosen = [study.dataset(n) for n in evaluated]
    runs = [Run(d.name, c, tuple(t for t in trainable if t.name != d.name), (d,))
            for d in chosen if d.role == "both" for c in conditions]
    tests = tuple(d for d in chosen if d.role == "test")
    return runs + [Run(ALL_RUN, c, trainable, tests) for c in conditions] if tests else runs


def what(run: Run, ds: Dataset, tag: str) -> str:
    return f"{tag} {'held out' if ds.role == 'both' else 'tested on'} {ds.name}, {run.condition}"


def pending(run: Run, out: Path, key: Callable[[Dataset], str], tag: str, say: Callable[[str], None],
            legacy: str | None = None) -> tuple[list[dict[str, Any]], list[Dataset]]:
    """(results finished earlier with settings ``key(ds)`` -- or ``legacy``, every setting of the
    study, as rows were keyed before :class:`vctrain.study.keys.Keys` --, datasets still to score);
    a result of other settings is removed."""
    run_dir = run.folder(out)
    rows, todo = [], []
    for ds in run.tests:
        f = run.result_file(run_dir, ds)
        prev = json.loads(f.read_text()) if f.exists() else None
        if prev is not None and prev.get("settings_sha") in (key(ds), legacy):
            rows.append(prev)
            say(f"{what(run, ds, tag)}: done earlier (IoU {prev['iou']:.3f})")
            continue
        if prev is not None:
            say(f"{what(run, ds, tag)}: the study's settings changed since it ran; redoing it")
            f.unlink()
        todo.append(ds)
    return rows, todo


def write_result(run: Run, out: Path, ds: Dataset, metrics: dict[str, Any], info: dict[str, Any], seconds: float,
                 sha: str, tag: str, say: Callable[[str], None], **extra: Any) -> dict[str, Any]:
    """Write and return the result row of ``ds`` in ``run`` (``info``: its model's training)."""
    row = {"heldout": ds.name, "condition": run.condition, "role": ds.role, "run": run.name, **metrics,
           **{k: info[k] for k in INFO}, **extra, "total_seconds": round(seconds, 1), "settings_sha": sha}
    write_json(run.result_file(run.folder(out), ds), row)
    say(f"{what(run, ds, tag)}: {row.get('output', 'road')} IoU {row['iou']:.3f} ({row['total_seconds']:.0f} s)")
    return row
