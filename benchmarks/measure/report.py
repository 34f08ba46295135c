"""What a result JSON records about its run (:func:`machine`, :func:`today`), writing it (:func:`write_json`)
and where it goes (:func:`results_dir`)."""
from __future__ import annotations

import json
import os
import platform
import time
from pathlib import Path


def machine() -> str:
    """The machine line of a result: architecture and cores, e.g. 'x86_64, 2 cores'."""
    return f"{platform.machine()}, {os.cpu_count()} cores"


def today() -> str:
    """The date line of a result (YYYY-MM-DD)."""
    return time.strftime("%Y-%m-%d")


def write_json(path: Path, data, indent: int = 1) -> Path:
    """``data`` as indented JSON (and a newline) at ``path``, its folder made if needed."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=indent) + "\n")
    return path


def results_dir(script: str | Path) -> Path:
    """A benchmark's results folder: ``results/`` beside the script (``benchmarks/<question>/results/``),
    where benchmarks/results_page.py reads its JSON."""
    return Path(script).resolve().parent / "results"
