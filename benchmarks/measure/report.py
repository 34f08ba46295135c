"""What a result JSON records about its run (:func:`machine`, :func:`today`, :func:`provenance`), writing it
(:func:`write_json`) and where it goes (:func:`results_dir`)."""
from __future__ import annotations

import importlib.metadata
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

# the libraries a result's figures can move with: name in the JSON -> (module, distributions that ship it)
LIBRARIES = {
    "torch": ("torch", ("torch",)),
    "opencv": ("cv2", ("opencv-python-headless", "opencv-python", "opencv-contrib-python-headless",
                       "opencv-contrib-python")),
    "numpy": ("numpy", ("numpy",)),
    "onnxruntime": ("onnxruntime", ("onnxruntime", "onnxruntime-gpu", "onnxruntime-openvino")),
    "openvino": ("openvino", ("openvino",)),
}


def machine() -> str:
    """The machine line of a result: architecture and cores, e.g. 'x86_64, 2 cores'."""
    return f"{platform.machine()}, {os.cpu_count()} cores"


def today() -> str:
    """The date line of a result (YYYY-MM-DD)."""
    return time.strftime("%Y-%m-%d")


def git_commit(repo: Path = REPO) -> dict:
    """``{"commit": short hash, "dirty": uncommitted changes}`` of ``repo``; both None without git or a
    repository."""
    def git(*args: str) -> str | None:
        try:
            run = subprocess.run(["git", "-C", str(repo), *args], capture_output=True, text=True, timeout=30)
        except (OSError, subprocess.SubprocessError):
            return None
        return run.stdout if run.returncode == 0 else None
    head = git("rev-parse", "--short", "HEAD")
    if head is None:
        return {"commit": None, "dirty": None}
    status = git("status", "--porcelain", "--untracked-files=no")
    return {"commit": head.strip(), "dirty": None if status is None else bool(status.strip())}


def library_version(module: str, dists: tuple[str, ...]) -> str | None:
    """A library's version without importing it: the loaded module's, else its installed distribution's,
    else None (not installed)."""
    loaded = sys.modules.get(module)
    if loaded is not None and isinstance(getattr(loaded, "__version__", None), str):
        return loaded.__version__
    for dist in dists:
        try:
            return importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            continue
    return None


def provenance() -> dict:
    """What a result was measured with: the git commit (and whether the tree was dirty), the library
    versions (None: not installed), the machine, its cores, Python and the date. Imports none of the
    libraries."""
    return {**git_commit(), "versions": {k: library_version(*v) for k, v in LIBRARIES.items()},
            "machine": machine(), "cores": os.cpu_count(), "python": platform.python_version(), "date": today()}


def write_json(path: Path, data, indent: int = 1) -> Path:
    """``data`` as indented JSON (and a newline) at ``path``, its folder made if needed. A dict without a
    ``provenance`` key gets one (:func:`provenance`); the caller's dict is left as it is."""
    if isinstance(data, dict) and "provenance" not in data:
        data = {**data, "provenance": provenance()}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=indent) + "\n")
    return path


def results_dir(script: str | Path) -> Path:
    """A benchmark's results folder: ``results/`` beside the script (``benchmarks/<question>/results/``),
    where benchmarks/results_page.py reads its JSON; an archived script's
    (``benchmarks/archive/<question>/``) is its question's, where its results stayed."""
    folder = Path(script).resolve().parent
    if folder.parent.name == "archive" and folder.parent.parent.name == "benchmarks":
        folder = folder.parent.parent / folder.name
    return folder / "results"
