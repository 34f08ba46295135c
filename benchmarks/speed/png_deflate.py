"""The store's PNG writer with each deflate candidate: milliseconds and kilobytes per image of the
store's own content, against OpenCV's encoder in the same run, and whether each candidate gives the
same bytes in fresh processes (issue 69 item 4).

Run:

    .venv/bin/python benchmarks/speed/png_deflate.py                   # 40 CamVid frames, 40 processes
    .venv/bin/python benchmarks/speed/png_deflate.py --processes 300   # a stronger determinism check

Data: the first ``--frames`` CamVid train frames (``../shared/data/camvid``, 480x360; synthetic
``render_road`` frames when absent, said so) warped into a store as ``benchmarks/speed/store.py``
builds it (scale 1/8 of the ``virtual`` preset, 688x350, projective completion). Content kinds, each
with its ``vcprep.io.images.PNG_KINDS`` filter: ``store`` (the store's images), ``label`` (its
labels), ``valid`` (its valid masks) and ``photo`` (the source frames, what ``vctrain predict``'s
overlays and the figures write).

Candidates (those not installed are listed as such): the encoder of ``vcprep.io.png`` (rows
filtered in numpy, one IDAT) with the deflate of the standard library's ``zlib``, ``zlib-ng``
(PyPI ``zlib-ng``) and ``libdeflate`` (PyPI ``deflate``) at several levels, each kind's filter and
the other filters at the chosen level; and ``cv2.imencode`` (OpenCV's libpng, its default settings
and level 1 with the default strategy). Time: per image the fastest of ``--repeats`` encodes, the
median over images; size: the mean. Every encoding is decoded by ``cv2.imdecode`` and compared.

Determinism: the filtered rows of 12 items of each kind are saved once; ``--processes`` fresh
interpreters (address-space randomisation on, an environment of random size, and before each
compress random-size buffers filled with random bytes allocated and freed, so the allocator hands
out dirty memory) deflate them at each level, on the main thread and then on 2 threads at once;
``distinct_streams`` counts the different streams per item (1 = deterministic in this run). ISA-L
differed in about 1 process of 500-3000 (issue 61): 40 processes cannot show so rare a difference,
300 can only make it unlikely; the design of the library is the argument (docs/development.md).

``versions`` in the JSON: the library's version for zlib and zlib-ng, the PyPI ``deflate`` wrapper's
for libdeflate (it bundles libdeflate, so its version fixes libdeflate's). Threads:
``cv2.setNumThreads(1)``. Results: ``benchmarks/speed/results/png_deflate.json``; the last stdout
line is one JSON object: ms and KB per store image for each candidate, and the determinism verdicts.
"""
from __future__ import annotations

import argparse
import hashlib
import importlib
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.report import results_dir, today, write_json
from benchmarks.speed.store import frames
from vcprep.camera import PRESETS
from vcprep.io import PNG_KINDS, png
from vcprep.labels import LABEL_FORMATS
from vcprep.store import Store, WarpSettings, warp_dataset

# deflate candidates: name -> (module, the call that gives a zlib stream of bytes at a level)
DEFLATES = {"zlib": ("zlib", "compress"), "zlib-ng": ("zlib_ng.zlib_ng", "compress"),
            "libdeflate": ("deflate", "zlib_compress")}
LEVELS = {"zlib": (1, 2, 3), "zlib-ng": (1, 2, 3), "libdeflate": (1, 2, 3, 4, 6)}
KIND_FILTER = {"store": PNG_KINDS["store"][0], "label": PNG_KINDS["mask"][0], "valid": PNG_KINDS["mask"][0],
               "photo": PNG_KINDS["photo"][0]}

# a fresh interpreter: deflate every saved row set at every level (after dirtying the heap), on the main
# thread and on 2 threads at once; print the SHA-256 of each stream
CHILD = r"""
import hashlib, importlib, json, os, random, sys, threading
import numpy as np
mod, fn, levels, rows, seed = sys.argv[1], sys.argv[2], json.loads(sys.argv[3]), sys.argv[4], int(sys.argv[5])
compress = getattr(importlib.import_module(mod), fn)
data = np.load(rows)
rnd = random.Random(seed)
keep = []
def dirty():
    for _ in range(rnd.randrange(1, 8)):
        b = bytearray(os.urandom(rnd.randrange(1, 1 << rnd.randrange(4, 19))))
        if rnd.random() < 0.3:
            keep.append(b)
    if len(keep) > 50:
        del keep[rnd.randrange(len(keep))]
def run(names, out):
    for k in names:
        for lv in levels:
            dirty()
            out[f"{k}@{lv}"] = hashlib.sha256(bytes(compress(data[k], lv))).hexdigest()
main, a, b = {}, {}, {}
run(list(data.files), main)
ts = [threading.Thread(target=run, args=(list(data.files), o)) for o in (a, b)]
[t.start() for t in ts]; [t.join() for t in ts]
print(json.dumps({"main": main, "threads_agree": a == main and b == main}))
"""


def load_deflates() -> tuple[dict, dict]:
    """The installed candidates' compress functions and each one's version (or 'not installed')."""
    fns, versions = {}, {}
    for name, (mod, fn) in DEFLATES.items():
        try:
            m = importlib.import_module(mod)
        except ImportError:
            versions[name] = "not installed"
            continue
        fns[name] = getattr(m, fn)
        versions[name] = (m.ZLIB_RUNTIME_VERSION if name == "zlib" else m.ZLIBNG_VERSION if name == "zlib-ng"
                          else f"PyPI deflate {m.__version__}")
    return fns, versions


def content(n: int, tmp: Path) -> tuple[dict, str]:
    """Arrays of each kind, decoded from a store built from ``n`` frames (and those frames)."""
    jobs, source = frames(n, tmp)
    out = tmp / "store"
    warp_dataset(jobs, out, WarpSettings(PRESETS["camvid"], PRESETS["virtual"], 0.125, LABEL_FORMATS["camvid"],
                                         completion="projective", workers=1, progress=False))
    store = Store.open(out)
    read = lambda p: cv2.imread(str(p), cv2.IMREAD_UNCHANGED)  # noqa: E731
    recs = [store.items[k] for k in sorted(store.items)]
    kinds = {"store": [read(out / r["image"]) for r in recs], "label": [read(out / r["label"]) for r in recs],
             "valid": [read(out / v) for v in sorted({r["valid"] for r in recs})],
             "photo": [read(j.image) for j in jobs]}
    return kinds, source


def encoders(fns: dict) -> dict:
    """Candidate name -> function (array, filter) -> PNG bytes."""
    enc = {}
    for name, compress in fns.items():
        for lv in LEVELS[name]:
            enc[f"{name} {lv}"] = (lambda c, l: lambda a, f: png.png_file(*_compressed(c, l, a, f)))(compress, lv)
    enc["cv2 default"] = lambda a, f: cv2.imencode(".png", a)[1].tobytes()
    enc["cv2 1 default-strategy"] = lambda a, f: cv2.imencode(".png", a, [cv2.IMWRITE_PNG_COMPRESSION, 1,
                                                                         cv2.IMWRITE_PNG_STRATEGY,
                                                                         cv2.IMWRITE_PNG_STRATEGY_DEFAULT])[1].tobytes()
    return enc


def _compressed(compress, level: int, a: np.ndarray, filt: str) -> tuple[bytes, bytes]:
    ihdr, raw = png.filtered_rows(a, filt)
    return ihdr, bytes(compress(raw, level))


def time_encoder(enc, arrays: list[np.ndarray], filt: str, repeats: int) -> dict:
    """Median over images of the fastest encode (ms), mean size (KB); every encoding decoded and compared."""
    best, sizes = [], []
    for a in arrays:
        ts = []
        for _ in range(repeats):
            t = time.perf_counter()
            data = enc(a, filt)
            ts.append(time.perf_counter() - t)
        back = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
        assert back is not None and np.array_equal(back.reshape(a.shape), a), "round trip failed"
        best.append(min(ts))
        sizes.append(len(data))
    return {"ms": 1000 * float(np.median(best)), "kb": float(np.mean(sizes)) / 1000}


def speed_table(kinds: dict, fns: dict, repeats: int, filters_of: str) -> dict:
    """{kind: {candidate: {ms, kb}}}: every candidate with each kind's filter, then ``filters_of``
    (a candidate name) with every filter."""
    enc = encoders(fns)
    table = {}
    for kind, arrays in kinds.items():
        row = {name: time_encoder(e, arrays, KIND_FILTER[kind], repeats) for name, e in enc.items()}
        if filters_of in enc:
            for f in png.FILTERS:
                row[f"{filters_of} filter={f}"] = time_encoder(enc[filters_of], arrays, f, repeats)
        table[kind] = row
    return table


def determinism(kinds: dict, fns: dict, processes: int, tmp: Path) -> dict:
    """Per candidate: fresh processes run, distinct streams per item (max), whether every process
    and thread gave the parent's streams."""
    rows = {f"{kind}{i}": png.filtered_rows(a, KIND_FILTER[kind])[1]
            for kind, arrays in kinds.items() for i, a in enumerate(arrays[:12])}
    path = tmp / "rows.npz"
    np.savez(path, **rows)
    verdict = {}
    for name in fns:
        mod, fn = DEFLATES[name]
        levels = list(LEVELS[name])
        ref = {f"{k}@{lv}": hashlib.sha256(bytes(fns[name](r, lv))).hexdigest() for k, r in rows.items() for lv in levels}
        seen = {k: {v} for k, v in ref.items()}
        threads_ok = True
        for p in range(processes):
            env = {**os.environ, "VCSEG_PAD": "x" * (97 * p % 4001)}  # shifts the stack
            out = subprocess.run([sys.executable, "-c", CHILD, mod, fn, json.dumps(levels), str(path), str(p)],
                                 capture_output=True, text=True, check=True, env=env).stdout
            got = json.loads(out)
            threads_ok &= got["threads_agree"]
            for k, v in got["main"].items():
                seen[k].add(v)
        distinct = max(len(v) for v in seen.values())
        verdict[name] = {"processes": processes, "items": len(rows), "levels": levels, "max_distinct_streams": distinct,
                         "threads_agree": threads_ok, "deterministic_in_this_run": distinct == 1 and threads_ok}
        print(f"determinism {name}: {processes} processes x {len(rows)} items x levels {levels}: "
              f"max {distinct} distinct stream(s) per item; threads agree: {threads_ok}", file=sys.stderr)
    return verdict


def print_table(table: dict) -> None:
    kinds = list(table)
    names = list(table[kinds[0]])
    print(f"{'encoder':<32}" + "".join(f"{k + ' ms':>11}{k + ' KB':>11}" for k in kinds))
    for n in names:
        print(f"{n:<32}" + "".join(f"{table[k][n]['ms']:>11.2f}{table[k][n]['kb']:>11.1f}" for k in kinds))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=40, help="CamVid frames warped into the store (default 40)")
    ap.add_argument("--repeats", type=int, default=5, help="encodes per image, the fastest kept (default 5)")
    ap.add_argument("--processes", type=int, default=40, help="fresh processes of the determinism check (default 40)")
    ap.add_argument("--filters-of", default=f"{png.DEFLATE} {PNG_KINDS['store'][1]}",
                    help="the candidate measured with every filter (default: the writer's deflate and level)")
    ap.add_argument("--out", type=Path, default=results_dir(__file__) / "png_deflate.json")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    fns, versions = load_deflates()
    tmp = Path(tempfile.mkdtemp(prefix="bench-png-"))
    try:
        kinds, source = content(args.frames, tmp)
        shapes = {k: list(v[0].shape) for k, v in kinds.items()}
        print(f"data: {source}; shapes {shapes}; deflates {versions}; threads: cv2.setNumThreads(1)", file=sys.stderr)
        table = speed_table(kinds, fns, args.repeats, args.filters_of)
        print_table(table)
        det = determinism(kinds, fns, args.processes, tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    result = {"benchmark": "png_deflate", "date": today(), "data": source,
              "command": " ".join(["python", "benchmarks/speed/png_deflate.py", *sys.argv[1:]]),
              "frames": args.frames,
              "items": {k: len(v) for k, v in kinds.items()}, "shapes": shapes, "filters": KIND_FILTER,
              "writer": {"deflate": png.DEFLATE, "kinds": PNG_KINDS}, "versions": versions,
              "machine": platform.machine(), "cores": os.cpu_count(), "loadavg_1min": os.getloadavg()[0],
              "python": platform.python_version(), "cv2": cv2.__version__, "threads": "cv2.setNumThreads(1)",
              "repeats": args.repeats, "ms_kb": table, "determinism": det}
    write_json(args.out, result)
    print(f"wrote {args.out}", file=sys.stderr)
    print(json.dumps({"store_image_ms": {n: round(v["ms"], 2) for n, v in table["store"].items()},
                      "store_image_kb": {n: round(v["kb"], 1) for n, v in table["store"].items()},
                      "deterministic": {n: v["deterministic_in_this_run"] for n, v in det.items()}}))


if __name__ == "__main__":
    main()
