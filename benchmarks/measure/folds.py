"""Leave-one-out folds: the command line of a study run fold by fold, and a held-out camera found from
its frames only, exactly as ``vctrain predict --camera estimate`` finds it (no test label read).

Shared by benchmarks/other_cameras/calibrated_loo.py, benchmarks/what_a_user_gets/ship_geometry.py and
the archived benchmarks/archive/other_cameras/merged_estimated.py, where they began.
"""
from __future__ import annotations

import argparse
from fnmatch import fnmatchcase
from pathlib import Path

import yaml

from .report import write_json


def fold_args(ap: argparse.ArgumentParser, every: list[str], workdir: Path) -> tuple[argparse.Namespace, list[str], list[int]]:
    """The options of a study run fold by fold added to ``ap`` (beside its own), parsed: (the arguments,
    the folds to run, a subset of ``every``, and the seeds: 0 alone in a smoke run)."""
    ap.add_argument("--held-out", default=",".join(every), help=f"the folds, a subset of {','.join(every)}, run in that order")
    ap.add_argument("--epochs", type=int, default=None, help="default: crossval's (the recipe's)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--workdir", type=Path, default=workdir)
    ap.add_argument("--quick", action="store_true", help="smoke run: a few frames, 2 steps, seed 0")
    ap.add_argument("--collect", action="store_true", help="run nothing: report what is finished")
    a = ap.parse_args()
    folds = [f for f in a.held_out.split(",") if f]
    if not folds or set(folds) - set(every):
        raise SystemExit(f"--held-out {a.held_out}: folds are {', '.join(every)}")
    return a, folds, [0] if a.quick else [int(s) for s in a.seeds.split(",") if s]


def frames_only_camera(fd: Path, entry: dict) -> Path:
    """The held-out set's camera from its frames alone, as ``vctrain predict --camera estimate`` gets it
    (kept in fd/frames-only.yaml, with what was estimated and assumed in a JSON beside it)."""
    path = fd / "frames-only.yaml"
    if path.is_file():
        return path
    from vcprep.camera import camera_to_yaml, estimate_camera
    from vcprep.dataset import list_dataset
    from vcprep.labels import get_label_format
    from vctrain.predict.road import folder_ego_camera

    test = entry["test"]  # (its include: a smoke run's subset, matched on the study's item ids: IDD's name the drive)
    jobs = list_dataset(test["images"], fmt=get_label_format(entry["label_format"]))
    globs = test.get("include", "*")
    files = [j.image for j in jobs if any(fnmatchcase(j.id, g) for g in ([globs] if isinstance(globs, str) else globs))]
    est = estimate_camera(files, name=f"{entry['name']}-frames-only")
    cam = folder_ego_camera(est.camera, files, "auto")
    fd.mkdir(parents=True, exist_ok=True)
    write_json(path.with_suffix(".json"), {**est.to_dict(), "camera": cam.to_dict(), "frames": len(files)})
    path.write_text(camera_to_yaml(cam))
    return path


def frames_only_entry(fd: Path, entry: dict) -> dict:
    """A study's test entry given its frames-only camera (:func:`frames_only_camera`, kept in ``fd``), in place."""
    cam = frames_only_camera(fd, entry)
    entry["camera"] = str(cam)
    if not yaml.safe_load(cam.read_text()).get("ego_rows"):
        entry["ego"] = "none"  # nothing found in the frames: crossval must not look in the test labels
    return entry
