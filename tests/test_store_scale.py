"""The store at scale: parallel and sharded builds, provenance, verify/info/merge, crash safety."""
from __future__ import annotations

import json
import os
import random
import shutil
import signal
import subprocess
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from conftest import PAPER_STORE, BIN, run_here, default_sigint, assert_one_error_line, run_cli, write_synthetic_dataset
from vcprep.store import Shard, Store

N_ITEMS = 40


@pytest.fixture(scope="module")
def ds(tmp_path_factory, camvid_half):
    root = tmp_path_factory.mktemp("scale")
    images, labels = write_synthetic_dataset(root, camvid_half, n=N_ITEMS, bonnet_rows=20)
    return images, labels


def _warp_args(images, labels, out, *extra):
    return ["warp", "--camera", "camvid", "--images", images, "--labels", labels, "--label-format", "camvid",
            "--out", out, *PAPER_STORE, *extra]


def _warp(images, labels, out, *extra):
    return run_cli(*_warp_args(images, labels, out, *extra))


def _files(store: Path) -> dict[str, bytes]:
    """Every file of a store (PNGs, store.json, manifest.jsonl), by relative path."""
    return {str(p.relative_to(store)): p.read_bytes() for p in sorted(store.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def reference(ds, tmp_path_factory):
    """An uninterrupted serial build: what every other build must reproduce byte for byte."""
    images, labels = ds
    out = tmp_path_factory.mktemp("ref") / "store"
    proc = _warp(images, labels, out, "--jobs", "1")
    assert proc.returncode == 0, proc.stderr
    assert f"{N_ITEMS} built, 0 up to date, 0 failed" in proc.stderr
    return out, _files(out)


def _verify(store, *extra, process=False):
    """``store verify --json``, one process (a 40-item store: a pool's start costs more than it
    saves); the pool's verify is test_verify_finds_each_kind_of_problem's. Unless ``process`` the
    command runs in this process (the console script's own entry point, :func:`conftest.run_here`):
    a new interpreter for each of the file's ~20 verifies cost ~0.5 s of CPU each, and reading a store
    is the same code either way (the builds it checks, and the kills, stay real processes)."""
    args = ["store", "verify", store, "--json", "--quiet", "-j", "1", *extra]
    proc = run_cli(*args) if process else run_here(*args)
    return proc, [json.loads(x) for x in proc.stdout.splitlines()]


# -- parallel ----------------------------------------------------------------------------------------

def test_jobs_2_is_byte_identical_to_jobs_1(ds, reference, tmp_path):
    images, labels = ds
    out = tmp_path / "store"
    proc = _warp(images, labels, out, "--jobs", "2")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(out)
    assert _files(out) == reference[1]
    # complete: 'none' then --jobs 2 projective gives the same store as warping with projective
    b = tmp_path / "b"
    assert _warp(images, labels, b, "--complete", "none", "-q").returncode == 0
    proc = run_cli("complete", b, "--jobs", "2")
    assert proc.returncode == 0 and f"{N_ITEMS} completed" in proc.stderr, proc.stderr
    assert _files(b) == reference[1]


# -- provenance and invalidation ---------------------------------------------------------------------

def test_provenance_and_exact_invalidation(ds, reference, tmp_path):
    images, labels = ds
    imgs, labs = tmp_path / "images", tmp_path / "labels"
    shutil.copytree(images, imgs)
    shutil.copytree(labels, labs)
    out = tmp_path / "store"
    assert _warp(imgs, labs, out, "-j", "2").returncode == 0
    params = json.loads((out / "store.json").read_text())
    assert params["scale"] == 0.125 and params["store_size"] == [688, 350] and params["virtual"]["name"] == "virtual"
    rec = Store.open(out).get("seq_0003")
    for k in ("source_sha256", "label_sha256", "camera_params", "H", "vp", "vp_status", "completion", "tool_version",
              "key", "files_sha256"):
        assert rec.get(k) is not None, k
    # a changed label redoes exactly its item
    lab = cv2.imread(str(labs / "seq_0005.png"), cv2.IMREAD_UNCHANGED)
    lab[200:210] = 3
    cv2.imwrite(str(labs / "seq_0005.png"), lab)
    proc = _warp(imgs, labs, out, "-j", "2")
    assert f"1 built, {N_ITEMS - 1} up to date" in proc.stderr, proc.stderr
    # another completion method redoes everything; a different scale is refused
    proc = _warp(imgs, labs, out, "-j", "2", "--complete", "zero")
    assert f"{N_ITEMS} built, 0 up to date" in proc.stderr, proc.stderr
    assert_one_error_line(_warp(imgs, labs, out, "--scale", "0.25"), "scale")


# -- verify / info -----------------------------------------------------------------------------------

def test_verify_finds_each_kind_of_problem(ds, reference, tmp_path):
    images, labels = ds
    imgs = tmp_path / "images"
    shutil.copytree(images, imgs)
    out = tmp_path / "store"
    assert _warp(imgs, labels, out, "-q").returncode == 0
    proc, problems = _verify(out)
    assert proc.returncode == 0 and problems == [], proc.stderr
    (out / "labels" / "seq_0001.png").unlink()                                   # missing
    (out / "images" / "seq_0002.png").write_bytes(b"\x89PNG\r\n\x1a\nbroken")   # corrupt
    cv2.imwrite(str(out / "labels" / "seq_0003.png"), np.full((350, 688), 7, np.uint8))  # bad values + checksum
    cv2.imwrite(str(out / "images" / "seq_0004.png"), np.zeros((10, 10, 3), np.uint8))  # wrong size
    cv2.imwrite(str(out / "images" / "stray.png"), np.zeros((10, 10), np.uint8))         # orphan
    (out / "labels" / ".seq_0009.png.abc.tmp").write_bytes(b"x")                          # temp file
    a = cv2.imread(str(imgs / "seq_0006.png"))
    cv2.imwrite(str(imgs / "seq_0006.png"), 255 - a)                                      # source changed
    proc, problems = _verify(out, "-j", "2", process=True)  # (the last -j counts; the pool in its own process)
    kinds = {(p["id"], p["kind"]) for p in problems}
    assert {("seq_0001", "missing"), ("seq_0002", "corrupt"), ("seq_0003", "values"), ("seq_0003", "checksum"),
            ("seq_0004", "size"), (None, "orphan"), (None, "temp"), ("seq_0006", "source changed")} <= kinds, kinds
    assert proc.returncode == 1
    err = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith("Error: ") and "5 bad items" in err[0]
    for i in ("seq_0001", "seq_0002", "seq_0003", "seq_0004", "seq_0006"):
        assert i in err[0]
    # text output: one line per problem, naming the item
    text = run_cli("store", "verify", out, "--no-sources", "-q")
    assert "seq_0006" not in text.stdout and "seq_0002\tcorrupt\timages/seq_0002.png" in text.stdout
    # --repair drops the items with bad files and the orphans; the build then redoes them
    proc = run_cli("store", "verify", out, "--repair", "-q")
    assert proc.returncode == 1 and "dropped 4 items" in proc.stderr, proc.stderr
    assert not (out / "images" / "stray.png").exists() and len(Store.open(out)) == N_ITEMS - 4
    proc = _warp(imgs, labels, out)
    assert "5 built" in proc.stderr, proc.stderr  # the 4 dropped + the changed source
    proc, problems = _verify(out)
    assert proc.returncode == 0 and problems == [], problems


def test_store_info(reference):
    out, _ = reference
    proc = run_here("store", "info", out, "--json")  # (one process; reads only)
    assert proc.returncode == 0, proc.stderr
    info = json.loads(proc.stdout)
    assert info["items"] == info["with_labels"] == N_ITEMS and info["store_size"] == [688, 350]
    assert info["scale"] == 0.125 and info["completion"] == {"projective": N_ITEMS}
    assert info["disk"]["images"]["files"] == N_ITEMS and info["disk_bytes"] > 0 and info["pending_parts"] == []
    text = run_here("store", "info", out)
    assert "items\t40 (40 with labels)" in text.stdout and "688x350" in text.stdout


def test_new_commands_have_help_with_an_example():
    for cmd in (["store", "verify"], ["store", "info"], ["store", "merge"], ["warp"], ["complete"]):
        proc = run_cli(*cmd, "--help")
        assert proc.returncode == 0 and "Example" in proc.stdout, cmd
    for opt in ("--jobs", "--shard", "--keep-going"):
        assert opt in run_cli("warp", "--help").stdout


# -- shared valid masks ------------------------------------------------------------------------------

def test_valid_masks_are_shared_per_geometry_and_pruned(ds, reference, tmp_path, camvid_half):
    """One valid mask per geometry (H, sizes): between-camera, all items share one file, equal to
    the coverage of the source rectangle; per-image VPs give one per pose; a rebuild that changes
    the geometry leaves no unused mask; repairing one item keeps the mask the others use."""
    from vcprep.warp import vp_from_pose

    images, labels = ds
    out, files = reference
    recs = list(Store.open(out))
    assert len({r["valid"] for r in recs}) == 1 and recs[0]["valid"].startswith("valid/H-")
    assert [k for k in files if k.startswith("valid/")] == [recs[0]["valid"]]
    valid = cv2.imread(str(out / recs[0]["valid"]), cv2.IMREAD_UNCHANGED)
    H = np.asarray(recs[0]["H"]).reshape(3, 3)
    cover = cv2.warpPerspective(np.ones((360, 480), np.uint8), H, (688, 350), flags=cv2.INTER_NEAREST,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    assert set(np.unique(valid)) == {0, 1} and np.mean(valid != cover) < 0.005  # differs on the edge at most
    # two poses: two masks, the items of each pose share theirs
    vps = tmp_path / "vps.csv"
    a, b = vp_from_pose(camvid_half, 2.0, 0.0), vp_from_pose(camvid_half, -2.0, 1.0)
    vps.write_text("id,u,v\n" + "".join(f"seq_{i:04d},{(a if i % 2 else b)[0]},{(a if i % 2 else b)[1]}\n"
                                        for i in range(N_ITEMS)))
    store = tmp_path / "store"
    assert _warp(images, labels, store, "--within", vps, "-q").returncode == 0
    recs = list(Store.open(store))
    assert len({r["valid"] for r in recs}) == 2
    assert len({r["valid"] for r in recs if int(r["id"][-4:]) % 2}) == 1
    # back to the average pose: every item rebuilt, the two masks are no longer used and are gone
    proc = _warp(images, labels, store, "-q")
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in (store / "valid").iterdir()) == [recs_name.split("/")[1] for recs_name in
                                                                   {r["valid"] for r in Store.open(store)}]
    assert _files(store) == files
    # a bad image: repair drops that item only; the shared mask stays for the others
    (store / "images" / "seq_0007.png").write_bytes(b"\x89PNG\r\n\x1a\nbroken")
    proc = run_cli("store", "verify", store, "--repair", "-q")
    assert proc.returncode == 1 and "dropped 1 item" in proc.stderr, proc.stderr
    proc, problems = _verify(store)
    assert proc.returncode == 0 and problems == [], problems
    assert _warp(images, labels, store, "-q").returncode == 0
    assert _files(store) == files


def test_stores_with_per_item_valid_masks_still_verify_and_migrate(ds, reference, tmp_path):
    """A store of the older layout (valid/ID.png per item) verifies; rebuilding an item or
    completing the store moves items to the shared mask and leaves no orphan."""
    images, labels = ds
    labs = tmp_path / "labels"
    shutil.copytree(labels, labs)
    out = tmp_path / "store"
    shutil.copytree(reference[0], out)
    store = Store.open(out)
    shared = store.path(next(iter(store))["valid"])
    for rec in store:
        shutil.copyfile(shared, out / "valid" / f"{rec['id']}.png")
        rec["valid"] = f"valid/{rec['id']}.png"
    shared.unlink()
    store.save()
    proc, problems = _verify(out)
    assert proc.returncode == 0 and problems == [], problems
    lab = cv2.imread(str(labs / "seq_0005.png"), cv2.IMREAD_UNCHANGED)
    lab[200:210] = 3
    cv2.imwrite(str(labs / "seq_0005.png"), lab)
    proc = _warp(images, labs, out, "-q")
    assert proc.returncode == 0, proc.stderr
    assert Store.open(out).get("seq_0005")["valid"] == shared.relative_to(out).as_posix()
    assert not (out / "valid" / "seq_0005.png").exists()
    proc, problems = _verify(out)
    assert proc.returncode == 0 and problems == [], problems
    assert run_cli("complete", out, "--method", "zero", "-q").returncode == 0
    assert sorted(p.name for p in (out / "valid").iterdir()) == [shared.name]
    proc, problems = _verify(out)
    assert proc.returncode == 0 and problems == [], problems


# -- shards ------------------------------------------------------------------------------------------

def test_shards_partition_the_ids():
    ids = [f"seq_{i:04d}" for i in range(500)]
    shards = [Shard(k, 4) for k in range(1, 5)]
    owners = [[s for s in shards if s.contains(i)] for i in ids]
    assert all(len(o) == 1 for o in owners)
    sizes = [sum(s.contains(i) for i in ids) for s in shards]
    assert min(sizes) > 90
    assert Shard.parse("2/4") == Shard(2, 4)


def test_sharded_build_merges_to_the_unsharded_store(ds, reference, tmp_path):
    images, labels = ds
    out = tmp_path / "store"
    procs = [subprocess.Popen([str(BIN / "vcprep"), *map(str, _warp_args(images, labels, out, "--shard", f"{k}/3",
                                                                          "-j", "1"))],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for k in (1, 2, 3)]
    results = [p.communicate(timeout=120) for p in procs]  # three 'machines' at once, no coordination
    assert all(p.returncode == 0 for p in procs), results
    assert sum(int(e.split(" items:")[0].split()[-1]) for _, e in results) == N_ITEMS
    # readable before the merge: the parts are read too
    assert len(Store.open(out)) == N_ITEMS
    info = json.loads(run_here("store", "info", out, "--json").stdout)
    assert len(info["pending_parts"]) == 3
    proc, problems = _verify(out)
    assert proc.returncode == 0 and problems == []
    proc = run_cli("store", "merge", out)
    assert proc.returncode == 0 and "merged 3 part files" in proc.stderr, proc.stderr
    assert _files(out) == reference[1]
    assert_one_error_line(_warp(images, labels, out, "--shard", "0/3"), "--shard")


# -- failures ----------------------------------------------------------------------------------------

def test_keep_going_skips_and_reports_bad_items(ds, tmp_path):
    images, labels = ds
    imgs = tmp_path / "images"
    shutil.copytree(images, imgs)
    (imgs / "seq_0007.png").write_bytes(b"")
    data = (imgs / "seq_0011.png").read_bytes()
    (imgs / "seq_0011.png").write_bytes(data[: len(data) // 2])
    out = tmp_path / "store"
    proc = _warp(imgs, labels, out, "--keep-going", "-j", "2")
    assert proc.returncode == 1 and proc.stdout.strip() == str(out)
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    failed = [ln for ln in lines if ln.startswith("failed: ")]
    assert len(failed) == 2 and "seq_0007.png" in failed[0] and "seq_0011.png" in failed[1]
    assert f"{N_ITEMS - 2} built, 0 up to date, 2 failed" in proc.stderr
    assert lines[-1].startswith("Error: ") and "2 of 40 items failed" in lines[-1]
    assert len(Store.open(out)) == N_ITEMS - 2
    proc, problems = _verify(out)
    assert proc.returncode == 0 and problems == []
    # default: stop at the first bad item, one Error line
    assert_one_error_line(_warp(imgs, labels, tmp_path / "s2", "-j", "2"), "seq_00")


# -- crash safety ------------------------------------------------------------------------------------

def _start(ds, out, jobs):
    images, labels = ds
    return subprocess.Popen([str(BIN / "vcprep"), *map(str, _warp_args(images, labels, out, "-j", str(jobs)))],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True, preexec_fn=default_sigint)


def _wait_until_building(proc, out, timeout=30.0):
    """Until the first record is journalled (the build loop runs) or the process ended."""
    t = time.monotonic() + timeout
    while proc.poll() is None and time.monotonic() < t:
        if (out / "manifest.journal.jsonl").exists():
            return
        time.sleep(0.005)


def test_sigkill_at_random_moments_then_resume_is_byte_identical(ds, reference, tmp_path):
    rng = random.Random(5)
    interrupted = 0
    # three rounds: a build of --jobs 1 killed, one of --jobs 2 killed, and one killed twice (--jobs 1,
    # then the resume with --jobs 2 killed again); each resumed to the reference store
    for round_ in range(3):
        out = tmp_path / f"store{round_}"
        for kill in range(2 if round_ == 2 else 1):  # the last round is killed twice
            proc = _start(ds, out, jobs=1 + (round_ + kill) % 2)
            _wait_until_building(proc, out)
            time.sleep(rng.uniform(0.0, 0.25))
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)  # the build and its workers, like a cluster's kill
            proc.communicate(timeout=60)
            n = len(Store.open(out))
            interrupted += n < N_ITEMS
            # everything recorded verifies; the only complaints are files of the items in flight
            vp, problems = _verify(out)
            assert all(p["id"] is None and p["kind"] in ("orphan", "temp") for p in problems), problems
            assert len([p for p in problems if p["kind"] == "orphan"]) <= 3 * 4  # <= window x 3 files
        proc = _warp(*ds, out, "-q")
        assert proc.returncode == 0, proc.stderr
        assert _files(out) == reference[1], f"round {round_}"
        vp, problems = _verify(out)
        assert vp.returncode == 0 and problems == []
    assert interrupted >= 2, "the kills should land mid-build"


@pytest.mark.parametrize("jobs", [1, 2])
def test_sigint_stops_cleanly_and_says_how_to_resume(ds, reference, tmp_path, jobs):
    out = tmp_path / "store"
    proc = _start(ds, out, jobs)
    _wait_until_building(proc, out)
    os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C: the whole foreground process group
    _, stderr = proc.communicate(timeout=60)
    if proc.returncode == 0:
        pytest.skip("the build finished before the signal")
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "run the same command again to resume" in stderr
    assert not list(out.glob("manifest.*.jsonl"))  # the journal was folded into the manifest
    vp, problems = _verify(out)
    assert vp.returncode == 0 and problems == []  # a clean stop leaves no orphans
    assert len(Store.open(out)) < N_ITEMS
    assert _warp(*ds, out, "-q").returncode == 0
    assert _files(out) == reference[1]


def _recorded_ids(store: Path) -> set[str]:
    """Ids recorded in the manifest or a part file (a torn last line ignored), read while a build runs;
    read again when a part is merged away between the listing and the read."""
    while True:
        ids = set()
        try:
            for part in store.glob("manifest*.jsonl"):
                for line in part.read_text().splitlines():
                    try:
                        ids.add(json.loads(line)["id"])
                    except ValueError:
                        pass
        except FileNotFoundError:
            continue
        return ids


def _kill_in_the_orphan_window(proc, out: Path, delay: float) -> None:
    """SIGKILL the build's process group ``delay`` s after it records its first item of this run,
    as soon as an image is in place that no record owns yet (a worker finished it, the parent has
    not recorded it), or 0.3 s later."""
    before = _recorded_ids(out) if out.is_dir() else set()
    t = time.monotonic() + 30.0
    while proc.poll() is None and time.monotonic() < t and not (_recorded_ids(out) - before if out.is_dir() else 0):
        time.sleep(0.002)
    time.sleep(delay)
    t = time.monotonic() + 0.3
    while proc.poll() is None and time.monotonic() < t:
        images = {p.stem for p in (out / "images").glob("*.png")}
        if images - _recorded_ids(out):
            break
        time.sleep(0.001)
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=60)


def test_verify_after_sigkill_of_a_parallel_build_fails_only_on_damage(ds, tmp_path):
    """A `--jobs 2` build killed (SIGKILL, process group) at three moments: verify exits 0 and
    reports the interrupted build's orphan and temp files (--strict fails on them); a record is
    never damaged. The next build removes every orphan, also one whose source is gone."""
    images, labels = tmp_path / "images", tmp_path / "labels"
    shutil.copytree(ds[0], images)
    shutil.copytree(ds[1], labels)
    out, left, strict_seen = tmp_path / "store", [], False
    for delay in (0.0, 0.03, 0.1):  # right at the first record of the run, and two moments later
        _kill_in_the_orphan_window(_start((images, labels), out, jobs=2), out, delay)
        proc = run_here("store", "verify", out, "--no-sources", "--json", "-q", "-j", "1")
        problems = [json.loads(x) for x in proc.stdout.splitlines()]
        assert proc.returncode == 0, proc.stderr  # nothing recorded is damaged
        assert all(p["id"] is None and p["kind"] in ("orphan", "temp") for p in problems), problems
        if problems and not strict_seen:
            strict = run_here("store", "verify", out, "--no-sources", "--strict", "-j", "1")
            assert strict.returncode == 1 and "orphan or temp file" in strict.stderr, strict.stderr
            strict_seen = True
        left.append([p["path"] for p in problems])
    # the next build removes the orphans, also an image whose source was deleted meanwhile
    strays = [Path(p).stem for p in left[-1] if p.startswith("images/") and p.endswith(".png")]
    if strays:
        stray, items = strays[0], N_ITEMS - 1
        (images / f"{stray}.png").unlink()
        (labels / f"{stray}.png").unlink()
    else:  # the last kill left only a temp file or a mask: an image of an item with no source at all
        stray, items = "gone", N_ITEMS
        shutil.copy(out / "images" / "seq_0000.png", out / "images" / f"{stray}.png")
    assert _warp(images, labels, out, "-q").returncode == 0
    proc = run_here("store", "verify", out, "--strict", "-j", "1")
    assert proc.returncode == 0 and proc.stdout == "", proc.stdout + proc.stderr
    assert len(Store.open(out)) == items and not (out / "images" / f"{stray}.png").exists()
