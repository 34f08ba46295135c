"""Throughput of the store stage (``vcprep warp`` into a fresh store) with 1 and 2 worker
processes, against plain PNG decode + encode of the same frames, in the same run.

Run:

    .venv/bin/python benchmarks/speed/store.py                      # all 367 CamVid train frames, 3 repeats
    .venv/bin/python benchmarks/speed/store.py --frames 120 --repeats 5

Data: ``../shared/data/camvid/train`` (all of it, or its first ``--frames`` images) (SegNet release, 480x360,
camvid camera) with their ``trainannot`` labels (camvid format), warped at scale 1/8 of the
``virtual`` preset (688x350) with projective completion (the paper's store). When that
folder is absent the script says so and uses synthetic ``render_road`` frames of the same size.

Timed per repeat (wall clock, fresh store each time, order of the three stages rotated):

* ``jobs1`` / ``jobs2``: :func:`vcprep.store.build.warp_dataset` with ``workers=1`` / ``2`` - the
  code of ``vcprep warp --jobs N`` (hash the sources, H, up-to-date check, warp + completion,
  three atomic PNG writes and a journalled record per item, the manifest at the end); the pool
  start-up is included;
* ``png_io``: for each frame, read + decode image and label, encode both as PNG (OpenCV's
  default settings) and write them atomically - plain PNG I/O of the same frames, the issue's
  baseline (``ratio_vs_png_io``);
* ``png_io_same_encoder``: the same, but encoding with the store's own PNG writer
  (``vcprep.io.png``, libdeflate since issue 69, zlib in issue 61, ISA-L before; image 'photo',
  label 'mask' settings of ``vcprep.io.images``). It encodes about 2x faster than OpenCV does
  (benchmarks/speed/png_deflate.py), so against ``png_io`` part of the store's ratio is the faster
  encoder; ``ratio_vs_same_encoder`` = jobs1 / this one is the store's cost over I/O done equally
  fast (reported, no target).

A pure-Python CPU loop run in 1 process and in a pool of 2 (``control_cpu_speedup``) measures,
interleaved with the stages, the speedup the machine allowed a second process during the run.
The table also gives the cores the whole machine kept busy during each stage (all processes,
from ``/proc/stat``; a pool's forkserver workers are not this process's children, so its own
rusage cannot see them) and the load average: on a shared machine other processes' load caps
what a second worker can add, and these say how much.

Threads: ``cv2.setNumThreads(1)`` in this process and in every worker (the pool is the
parallelism). Targets (issues 5 and 69): ``jobs2_speedup`` = jobs1 time / jobs2 time >= 1.7 on a
2-core machine; ``ratio_vs_png_io`` = jobs1 time / png_io time <= 1.1 (1.25 in issue 5). Results
(median, 10th-90th percentile and min-max over repeats): ``benchmarks/speed/results/store.json``; the
last stdout line is one JSON object with ``jobs1_items_s``, ``jobs2_items_s``, ``jobs2_speedup``,
``ratio_vs_png_io``.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path

import cv2
import deflate
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import SHARED_DATA
from benchmarks.measure.report import results_dir, today, write_json
from vcprep.dataset import Job, list_dataset
from vcprep.store import WarpSettings, warp_dataset
from vcprep.camera import PRESETS
from vcprep.io import png, write_bytes_atomic, write_png
from vcprep.labels import LABEL_FORMATS
from vcprep.store import default_jobs
from vcprep.synthetic import RoadScene, render_road

CAMVID = SHARED_DATA / "camvid"


def frames(n: int, tmp: Path) -> tuple[list[Job], str]:
    """Jobs for the benchmark frames and a sentence about where they came from."""
    fmt = LABEL_FORMATS["camvid"]
    if (CAMVID / "train").is_dir() and (CAMVID / "trainannot").is_dir():
        jobs = list_dataset(CAMVID / "train", CAMVID / "trainannot", fmt)[:n or None]
        return jobs, f"{'first ' if n else 'all '}{len(jobs)} CamVid train frames from {CAMVID} (480x360) with trainannot labels"
    n = n or 120
    jobs = list_dataset(*synthetic_frames(tmp / "synthetic", n), fmt)
    return jobs, f"{CAMVID} ABSENT: {n} synthetic render_road frames (480x360) instead"


def synthetic_frames(folder: Path, n: int) -> tuple[Path, Path]:
    """``n`` render_road frames through the camvid camera at 480x360 in ``folder/images`` and their
    camvid labels (road 3, else 0, the bottom 20 rows 11 = ignore, a bonnet) in ``folder/labels``."""
    cam = PRESETS["camvid"].for_image_size((480, 360))
    images, labels = folder / "images", folder / "labels"
    for d in (images, labels):
        d.mkdir(parents=True, exist_ok=True)
    for i in range(n):
        img, road = render_road(cam, RoadScene(offset=0.3 * i, texture_seed=i), supersample=1)
        ids = np.where(road == 1, 3, 0).astype(np.uint8)
        ids[-20:] = 11
        cv2.imwrite(str(images / f"seq_{i:04d}.png"), img)
        cv2.imwrite(str(labels / f"seq_{i:04d}.png"), ids)
    return images, labels


def _opencv_png(path: Path, arr: np.ndarray, kind: str) -> None:
    ok, buf = cv2.imencode(".png", arr)  # OpenCV's default PNG settings
    write_bytes_atomic(path, buf.tobytes())


def _our_png(path: Path, arr: np.ndarray, kind: str) -> None:
    write_png(path, arr, kind=kind)


def png_io(jobs: list[Job], out: Path, write=_opencv_png) -> None:
    """The baseline: decode + encode + atomic write of every image and label (``write``:
    OpenCV's encoder, or the store's own PNG writer for ``png_io_same_encoder``)."""
    out.mkdir(parents=True, exist_ok=True)
    for j in jobs:
        for src, tag, kind in ((j.image, "i", "photo"), (j.label, "l", "mask")):
            arr = cv2.imdecode(np.frombuffer(src.read_bytes(), np.uint8), cv2.IMREAD_UNCHANGED)
            write(out / f"{j.id}.{tag}.png", arr, kind)


def _burn(n: int) -> int:
    x = 0
    for i in range(n):
        x += i * i
    return x


def control(workers: int, tasks: int = 4, n: int = 2_000_000) -> float:
    """Seconds for ``tasks`` pure-Python CPU loops in 1 process or a pool of ``workers``: the
    speedup the machine allows right now, whatever our code does."""
    t = time.perf_counter()
    if workers == 1:
        [_burn(n) for _ in range(tasks)]
    else:
        import concurrent.futures as cf

        with cf.ProcessPoolExecutor(workers) as pool:
            list(pool.map(_burn, [n] * tasks))
    return time.perf_counter() - t


def cpu_s() -> float:
    """Busy CPU seconds of the whole machine so far (``/proc/stat``: all but idle and iowait);
    without it, this process's and its waited-for children's."""
    try:
        f = [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
        return (sum(f) - f[3] - f[4]) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        a, b = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
        return a.ru_utime + a.ru_stime + b.ru_utime + b.ru_stime


def stats(ts: list[float]) -> dict:
    a = np.array(ts)
    return {"median_s": float(np.median(a)), "p10_s": float(np.percentile(a, 10)), "p90_s": float(np.percentile(a, 90)),
            "min_s": float(a.min()), "max_s": float(a.max()), "runs": len(ts)}


def stage_runs(jobs: list[Job], tmp: Path, scale: float) -> dict:
    """The timed stages, each a function of the repeat index returning seconds: the store build
    with 1 and 2 workers, the PNG baselines, and the pure-CPU control with 1 and 2 processes."""
    cam, virtual, fmt = PRESETS["camvid"], PRESETS["virtual"], LABEL_FORMATS["camvid"]

    def build(workers: int, run: int) -> float:
        out = tmp / f"store-{workers}-{run}"
        t = time.perf_counter()
        store, summary = warp_dataset(jobs, out, WarpSettings(cam, virtual, scale, fmt, completion="projective",
                                                              workers=workers, progress=False))
        dt = time.perf_counter() - t
        assert summary.built == len(jobs), summary.line()
        shutil.rmtree(out)
        return dt

    def baseline(fn, run: int) -> float:
        out = tmp / f"png-{run}"
        t = time.perf_counter()
        fn(jobs, out)
        dt = time.perf_counter() - t
        shutil.rmtree(out)
        return dt

    return {"jobs1": lambda r: build(1, r), "jobs2": lambda r: build(2, r), "png_io": lambda r: baseline(png_io, r),
            "png_io_same_encoder": lambda r: baseline(lambda j, o: png_io(j, o, _our_png), r),
            "cpu1": lambda r: control(1), "cpu2": lambda r: control(2)}


def own_cpu_s() -> float:
    """CPU seconds of this process so far (not of its pool's workers)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def time_stages(stages: dict, repeats: int) -> tuple[dict, dict, dict, list[float]]:
    """Seconds, busy machine CPU seconds and this process's CPU seconds of each stage per repeat (the
    stages in a rotated order each repeat, after one warm-up build), and the 1-minute load average
    before and after."""
    stages["jobs1"](-1)  # warm-up: imports, page cache of the frames
    times: dict[str, list[float]] = {k: [] for k in stages}
    cpu: dict[str, list[float]] = {k: [] for k in stages}
    own: dict[str, list[float]] = {k: [] for k in stages}
    names = list(stages)
    load_before = os.getloadavg()[0]
    for r in range(repeats):
        for k in names[r % len(names):] + names[:r % len(names)]:
            c, o = cpu_s(), own_cpu_s()
            times[k].append(stages[k](r))
            cpu[k].append(cpu_s() - c)
            own[k].append(own_cpu_s() - o)
    return times, cpu, own, [load_before, os.getloadavg()[0]]


def report(times: dict, cpu: dict, own: dict, loads: list[float], n: int, source: str,
           args: argparse.Namespace) -> dict:
    """Print the table and the verdicts; the result record. Besides the ratios of median wall times:
    ``ratio_vs_png_io_paired``, the median over repeats of jobs1 / png_io of the same repeat (run
    next to each other: less exposed to load that changes during the run), and
    ``ratio_vs_png_io_cpu``, the same of this process's CPU seconds (both in-process; time the
    process waited for a core is not in it)."""
    names = list(times)
    st = {k: stats(v) for k, v in times.items()}
    med = {k: v["median_s"] for k, v in st.items()}
    speedup = med["jobs1"] / med["jobs2"]
    machine = med["cpu1"] / med["cpu2"]
    ratio = med["jobs1"] / med["png_io"]
    ratio_same = med["jobs1"] / med["png_io_same_encoder"]
    paired = float(np.median(np.array(times["jobs1"]) / np.array(times["png_io"])))
    ratio_cpu = float(np.median(np.array(own["jobs1"]) / np.array(own["png_io"])))
    virtual = PRESETS["virtual"]
    store_size = [round(virtual.size[0] * args.scale), round(virtual.size[1] * args.scale)]
    cores_used = {k: float(np.median(np.array(cpu[k]) / np.array(times[k]))) for k in names}
    print(f"{'stage':<20} {'items/s':>8} {'ms/item':>8} {'median s':>9} {'p10..p90 s':>14} {'min..max s':>14} "
          f"{'machine cores busy':>18}")
    for k in names[:4]:
        s = st[k]
        print(f"{k:<20} {n / s['median_s']:>8.1f} {1000 * s['median_s'] / n:>8.2f} {s['median_s']:>9.3f} "
              f"{s['p10_s']:>6.3f}..{s['p90_s']:<6.3f} {s['min_s']:>6.3f}..{s['max_s']:<6.3f} {cores_used[k]:>18.2f}")
    print(f"load average (1 min) before/after: {loads[0]:.2f}/{loads[1]:.2f} on {os.cpu_count()} cores "
          "(other processes' load leaves the pool fewer cores)")
    print(f"jobs2 speedup {speedup:.2f}x (target >= 1.7); a pure-CPU control got {machine:.2f}x from 2 processes "
          f"in the same run (what the machine allowed)")
    print(f"store stage / PNG decode+encode {ratio:.2f}x (target <= 1.1; paired by repeat {paired:.2f}x, in this "
          f"process's CPU time {ratio_cpu:.2f}x); / the same with the store's PNG writer {ratio_same:.2f}x")
    return {"benchmark": "store", "data": source, "frames": n, "source_size": [480, 360],
            "store_size": store_size, "scale": args.scale, "completion": "projective",
            "threads": "cv2.setNumThreads(1) per process", "cores": default_jobs(),
            "machine": platform.machine(), "python": platform.python_version(), "cv2": cv2.__version__,
            "deflate": png.DEFLATE + (f" (PyPI deflate {deflate.__version__})" if png.DEFLATE == "libdeflate" else ""),
            "date": today(),
            "command": " ".join(["python", "benchmarks/speed/store.py", *sys.argv[1:]]),
            "repeats": args.repeats, "stages": st, "cores_busy": cores_used,
            "machine_busy_ms_per_item": {k: 1000 * float(np.median(cpu[k])) / n for k in names},
            "loadavg_1min": loads,
            "items_s": {k: n / med[k] for k in names[:4]},
            "process_cpu_ms_per_item": {k: 1000 * float(np.median(own[k])) / n for k in names
                                        if k not in ("jobs2", "cpu2")},  # (a pool's workers are other processes)
            "jobs2_speedup": speedup, "ratio_vs_png_io": ratio, "ratio_vs_png_io_paired": paired,
            "ratio_vs_png_io_cpu": ratio_cpu,
            "ratio_vs_same_encoder": ratio_same, "control_cpu_speedup": machine,
            "targets": {"jobs2_speedup": ">= 1.7", "ratio_vs_png_io": "<= 1.1"}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=0, help="number of frames (default 0: all of camvid/train)")
    ap.add_argument("--repeats", type=int, default=3, help="timed repeats of each stage (default 3)")
    ap.add_argument("--scale", type=float, default=0.125, help="store scale (default 1/8 -> 688x350)")
    ap.add_argument("--out", type=Path, default=results_dir(__file__) / "store.json")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    tmp = Path(tempfile.mkdtemp(prefix="bench-store-"))
    try:
        jobs, source = frames(args.frames, tmp)
        print(f"data: {source}; cores available: {default_jobs()}; threads: cv2.setNumThreads(1) per process",
              file=sys.stderr)
        times, cpu, own, loads = time_stages(stage_runs(jobs, tmp, args.scale), args.repeats)
        result = report(times, cpu, own, loads, len(jobs), source, args)
        write_json(args.out, result)
        print(f"wrote {args.out}", file=sys.stderr)
        n, med, cores_used = len(jobs), {k: v["median_s"] for k, v in result["stages"].items()}, result["cores_busy"]
        print(json.dumps({"jobs1_items_s": round(n / med["jobs1"], 2), "jobs2_items_s": round(n / med["jobs2"], 2),
                          "png_io_items_s": round(n / med["png_io"], 2), "jobs2_speedup": round(result["jobs2_speedup"], 3),
                          "control_cpu_speedup": round(result["control_cpu_speedup"], 3),
                          "ratio_vs_png_io": round(result["ratio_vs_png_io"], 3),
                          "ratio_vs_png_io_paired": round(result["ratio_vs_png_io_paired"], 3),
                          "ratio_vs_png_io_cpu": round(result["ratio_vs_png_io_cpu"], 3),
                          "ratio_vs_same_encoder": round(result["ratio_vs_same_encoder"], 3), "frames": n,
                          "jobs2_cores_busy": round(cores_used["jobs2"], 2), "loadavg": round(loads[0], 2),
                          "camvid": "ABSENT" not in source}))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
