"""Crossval studies as the benchmarks run them: a study file written (:func:`write_study`), a smoke
run's few frames linked (:func:`subset_links`, :func:`subset_glob`), one ``vctrain crossval`` run
resumed where it stopped (:func:`run_study`), the stores shared between seeds (:func:`link_stores`,
:func:`share_stores`), and the CamVid model's step budget the merged-camera studies train with
(:func:`camvid_steps_per_epoch`).

Began in benchmarks/other_cameras/as_shipped.py (which still imports them by these names); used by
its studies, multi_camera.py, calibrated_loo.py, ship_loo.py and the shipped model's scripts.
"""
from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path

import yaml

from vctrain.training import DEFAULT_RECIPE, RECIPES, VAL_FRACTION

from .data import BIN, DATA, link_files, run

BATCH = RECIPES[DEFAULT_RECIPE]["batch_size"]  # the recipe's (vctrain fit's and crossval's default)


def write_study(wd: Path, name: str, datasets: list[dict], train: dict, extra: dict | None = None) -> Path:
    """wd/name: a crossval study of ``datasets`` (and ``extra`` top-level keys), ``train`` its training
    settings where any."""
    path = wd / name
    path.write_text(yaml.safe_dump({"datasets": datasets, **(extra or {}), **({"train": train} if train else {})},
                                   sort_keys=False))
    return path


def subset_links(src: Path, dst: Path, n: int, sub=("images", "labels")) -> tuple[str, str]:
    """dst/{images,labels}: links to the first ``n`` files of each folder of ``src`` (a smoke run)."""
    for s in sub:
        link_files([f.name for f in sorted((src / s).iterdir())[:n]], src / s, dst / s)
    return str(dst / sub[0]), str(dst / sub[1])


def subset_glob(images: Path, labels: Path, pattern: str, dst: Path) -> tuple[Path, Path]:
    """dst/{images,labels}: links to the frames of ``images`` (and their labels) that match ``pattern``."""
    names = [p.name for p in sorted(images.glob(pattern))]
    return link_files(names, images, dst / "images"), link_files(names, labels, dst / "labels")


def run_study(study: Path, out: Path, conds: list[str], seed: int, threads: int,
              heldout: list[str] | None = None) -> tuple[list[dict], dict]:
    """One crossval run (resumed where it stopped; only the evaluated datasets ``heldout`` when
    given): its result rows and its study.json."""
    t0 = time.time()
    pick = ["--heldout", ",".join(heldout)] if heldout else []
    run(BIN / "vctrain", "crossval", study, "--out", out, "--conditions", ",".join(conds), "--seed", seed,
        "--jobs", threads, "--json", *pick, stream=True, env={"OMP_NUM_THREADS": str(threads)})
    print(f"{out}: {time.time() - t0:.0f} s", flush=True)
    rows = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    return rows, json.loads((out / "study.json").read_text())


def link_stores(out: Path, src: Path) -> None:
    """out/{stores,vps,cameras} -> src's (relative links): they do not depend on the seed or the
    training settings, so they are built once (crossval's store locks and finished-store checks make
    the sharing safe). Existing entries are kept."""
    for sub in ("stores", "vps", "cameras"):
        link = out / sub
        if not link.exists() and not link.is_symlink():
            link.parent.mkdir(parents=True, exist_ok=True)
            link.symlink_to(Path(os.path.relpath(src / sub, out)))
            (src / sub).mkdir(parents=True, exist_ok=True)


def share_stores(wd: Path, seed: int, first: int) -> None:
    """WORKDIR/seed<seed>/{stores,vps,cameras} -> seed<first>'s."""
    if seed != first:
        link_stores(wd / f"seed{seed}", wd / f"seed{first}")


def camvid_steps_per_epoch() -> int:
    """The CamVid model's steps per epoch in study 1 (its frames less the validation share, batch 8)."""
    n = sum(1 for p in (DATA / "train").glob("*.png") if not p.name.startswith("0001TP_"))
    return math.ceil((n - round(VAL_FRACTION * n)) / BATCH)
