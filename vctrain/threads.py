"""How many threads a command computes with: torch's intra-op pool, OpenCV's and onnxruntime's
(``--threads`` of ``vctrain predict``, ``vctrain export`` and ``vctrain fit``).

torch's OpenMP pool meets at a barrier after every operator. When another process holds one of
the cores, the thread on it waits for its time slice at each barrier, and a frame takes several
times as long as at one thread: the shipped model on the example frames ran at 1.2-1.4 s a frame
at torch's default 2 threads on a loaded 2-core machine, 0.08-0.13 s at one (issue 45; the
measurement is in the docstring of :func:`default_threads`). So the default is the cores no other
process is running on when the command starts, at least 1 and at most torch's own default.
"""
from __future__ import annotations

import math
import os
import statistics
import time
from pathlib import Path

import cv2
import torch

__all__ = ["available_cpus", "busy_cpus", "default_threads", "use_threads", "threads_in_use"]

_TORCH_DEFAULT = torch.get_num_threads()  # torch's own choice (the physical cores), before anything sets it


def available_cpus() -> int:
    """The CPUs this process may run on: its affinity, capped by a cgroup (v2) CPU quota."""
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    try:
        quota, period = Path("/sys/fs/cgroup/cpu.max").read_text().split()[:2]
        if quota != "max":
            cpus = min(cpus, max(1, math.ceil(int(quota) / int(period))))
    except (OSError, ValueError):
        pass
    return cpus


def busy_cpus(samples: int = 5, interval_s: float = 0.01) -> int:
    """Other processes running now: the median over ``samples`` reads, ``interval_s`` apart, of the
    kernel's count of running tasks (``procs_running`` in /proc/stat) less this one; where there
    is no /proc/stat, the 1-minute load average (rounded)."""
    counts = []
    for i in range(samples):
        try:
            text = Path("/proc/stat").read_text()
        except OSError:
            break
        running = [ln.split()[1] for ln in text.splitlines() if ln.startswith("procs_running ")]
        if not running:
            break
        counts.append(int(running[0]) - 1)
        if i + 1 < samples:
            time.sleep(interval_s)
    if counts:
        return max(0, round(statistics.median(counts)))
    try:
        return round(os.getloadavg()[0])
    except (AttributeError, OSError):
        return 0


def default_threads() -> int:
    """``OMP_NUM_THREADS`` where it is set (what torch itself would take), else the cores no other
    process is running on now (:func:`available_cpus` less :func:`busy_cpus`), at least 1, at most
    torch's own default.

    Measured by ``benchmarks/speed/predict_threads.py`` (the shipped model on the example frames, a
    2-core machine other jobs were using; benchmarks/results/predict_threads.json): beside 0, 1
    and 2 busy processes 2 threads took several times as long a frame as 1; the default chose 1
    and took the time of 1 (the target: at most 1.5x with 2 busy processes). On an idle machine
    it is torch's default (2 cores: 2 threads, somewhat faster than 1:
    benchmarks/results/shipped_model.json's predict_ms_1280x720_t1 / _t2)."""
    env = os.environ.get("OMP_NUM_THREADS", "").strip()
    if env.isdigit() and int(env) > 0:
        return int(env)
    return max(1, min(_TORCH_DEFAULT, available_cpus() - busy_cpus()))


def use_threads(threads: int | None = None) -> int:
    """Pin torch and OpenCV (and the onnxruntime sessions made afterwards,
    :func:`threads_in_use`) to ``threads`` (None: :func:`default_threads`). Returns the count."""
    n = default_threads() if threads is None else max(1, int(threads))
    torch.set_num_threads(n)
    cv2.setNumThreads(n)
    return n


def threads_in_use() -> int:
    """The threads set by :func:`use_threads` (torch's count): what an onnxruntime session uses."""
    return torch.get_num_threads()
