"""Concurrent writers of one store (issue 16.1): real processes, nothing killed.

The store lock (``STORE/store.lock``, :func:`vcprep.store.store_lock`) serialises unsharded
writers and lets shards run together; a writer that has to wait says so on stderr.
"""
from __future__ import annotations

import json
import os
import selectors
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import BIN, assert_one_error_line, run_cli, write_synthetic_dataset
from vcprep.synthetic import RoadScene

N = 30  # images per dataset, as in the issue


@pytest.fixture(scope="module")
def two_datasets(tmp_path_factory, camvid_half):
    root = tmp_path_factory.mktemp("lock")
    a = write_synthetic_dataset(root / "a", camvid_half, n=N, bonnet_rows=20)
    b = write_synthetic_dataset(root / "b", camvid_half, n=N, bonnet_rows=20, scene=RoadScene(offset=1.0))
    return a, b


def _warp_cmd(ds, out, *extra):
    images, labels = ds
    return [str(BIN / "vcprep"), "warp", "--camera", "camvid", "--images", str(images), "--labels", str(labels),
            "--label-format", "camvid", "--out", str(out), "--jobs", "1", *map(str, extra)]


def _manifest_ids(store: Path) -> list[str]:
    return [json.loads(x)["id"] for x in (store / "manifest.jsonl").read_text().splitlines() if x.strip()]


def test_two_warps_started_together_keep_every_record(two_datasets, tmp_path):
    """What `make -j` does with two datasets sharing a store through --id-prefix: both must keep
    all 2N records. The two builds are made to overlap, not left to the scheduler (on a loaded
    machine one often finished before the other reached the lock): both are started while another
    process holds the lock, and released together, so one builds while the other waits for it."""
    out = tmp_path / "shared"
    holder = Holder(out)
    procs = [subprocess.Popen(_warp_cmd(ds, out, "--id-prefix", p), stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for ds, p in zip(two_datasets, ("a_", "b_"))]
    try:
        said = [_stderr_until(p, "waiting for the store lock") for p in procs]
    finally:
        holder.release()
    results = [p.communicate(timeout=300) for p in procs]
    for p, (so, se) in zip(procs, results):
        assert p.returncode == 0, se
        assert so.strip() == str(out)
        assert "got the store lock after" in se
    assert all(f"held by pid {holder.proc.pid} (" in x for x in said)
    ids = _manifest_ids(out)
    assert sorted(ids) == sorted([f"a_seq_{i:04d}" for i in range(N)] + [f"b_seq_{i:04d}" for i in range(N)])
    assert not list(out.glob("manifest.*.jsonl"))  # every part folded
    proc = run_cli("store", "verify", out, "--quiet")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout == ""  # no orphan, no missing file
    assert (out / "store.lock").read_bytes() == b""  # released: the holder's note is gone


# -- a lock held by another real process -------------------------------------------------------------

HOLD = ("import sys\n"
        "from vcprep.store import store_lock\n"
        "with store_lock(sys.argv[1], shared=sys.argv[2] == 'shared'):\n"
        "    print('locked', flush=True)\n"
        "    sys.stdin.readline()\n")


class Holder:
    """A separate process that holds the store lock until released."""

    def __init__(self, store: Path, shared: bool = False):
        self.proc = subprocess.Popen([sys.executable, "-c", HOLD, str(store), "shared" if shared else "exclusive"],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        assert self.proc.stdout.readline().strip() == "locked"

    def release(self) -> None:
        self.proc.stdin.write("\n")
        self.proc.stdin.flush()
        assert self.proc.wait(timeout=30) == 0


def _stderr_until(proc: subprocess.Popen, needle: str, timeout: float = 60.0) -> str:
    """stderr of ``proc`` up to the first line containing ``needle`` (fails on timeout or exit)."""
    sel = selectors.DefaultSelector()
    sel.register(proc.stderr, selectors.EVENT_READ)
    text, t0 = "", time.monotonic()
    while needle not in text:
        assert time.monotonic() - t0 < timeout, f"no '{needle}' on stderr after {timeout} s: {text!r}"
        if sel.select(timeout=1.0):
            line = proc.stderr.readline()
            assert line, f"process ended without '{needle}': {text!r}"
            text += line
    return text


@pytest.fixture(scope="module")
def built_a(two_datasets, tmp_path_factory):
    """Dataset a warped into a store once; each test writes to its own copy (:func:`_built_store`)."""
    out = tmp_path_factory.mktemp("built") / "store"
    proc = subprocess.run(_warp_cmd(two_datasets[0], out, "--quiet"), capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return out


def _built_store(built: Path, out: Path) -> Path:
    """A copy of the built store: the same records, files and sources (absolute), at ``out``."""
    shutil.copytree(built, out)
    return out


def _make_orphan(store: Path) -> Path:
    orphan = store / "images" / "stray.png"
    shutil.copy(next((store / "images").iterdir()), orphan)
    return orphan


@pytest.mark.parametrize("command", ["warp", "complete", "merge", "repair"])
def test_each_writer_waits_for_the_lock_and_says_so(command, two_datasets, built_a, tmp_path):
    a, b = two_datasets
    out = _built_store(built_a, tmp_path / "store")
    before = (out / "manifest.jsonl").read_bytes()
    if command == "warp":  # a second dataset into the same store
        cmd = _warp_cmd(b, out, "--id-prefix", "b_")
    elif command == "complete":
        cmd = [str(BIN / "vcprep"), "complete", str(out), "--method", "zero", "--jobs", "1"]
    elif command == "merge":
        cmd = [str(BIN / "vcprep"), "store", "merge", str(out)]
    else:
        orphan = _make_orphan(out)
        cmd = [str(BIN / "vcprep"), "store", "verify", str(out), "--repair", "--jobs", "1"]
    holder = Holder(out)
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        said = _stderr_until(proc, "waiting for the store lock")
        assert f"{out}: waiting for the store lock {out / 'store.lock'}, held by pid {holder.proc.pid} (" in said
        time.sleep(1.0)
        assert proc.poll() is None  # still waiting
        assert (out / "manifest.jsonl").read_bytes() == before  # and has written nothing
        if command == "repair":
            assert orphan.exists()
    finally:
        holder.release()
    so, se = proc.communicate(timeout=300)
    assert "got the store lock after" in se
    if command == "repair":  # verify reports the orphan (no damage: exit 0) and deletes it
        assert proc.returncode == 0 and "stray.png" in so and "repaired" in se, se
        assert not orphan.exists()
    else:
        assert proc.returncode == 0, se
    ids = _manifest_ids(out)
    assert len(ids) == (2 * N if command == "warp" else N)
    check = run_cli("store", "verify", out, "--quiet")
    assert check.returncode == 0, check.stdout + check.stderr


def test_shards_share_the_lock_and_wait_for_an_exclusive_writer(two_datasets, built_a, tmp_path):
    a, _ = two_datasets
    out = _built_store(built_a, tmp_path / "store")
    # another shard holds the lock shared: this shard runs at once, without waiting
    holder = Holder(out, shared=True)
    try:
        proc = subprocess.run(_warp_cmd(a, out, "--shard", "1/2", "--complete", "zero"), capture_output=True,
                              text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr
        assert "waiting" not in proc.stderr
        # ... but an unsharded writer (which folds and deletes shard part files) waits for the shards
        merge = subprocess.Popen([str(BIN / "vcprep"), "store", "merge", str(out)], stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True)
        said = _stderr_until(merge, "waiting for the store lock")
        assert "held by another vcprep writer" in said  # shared holders leave no note
        assert list(out.glob("manifest.shard-1-of-2.jsonl"))
    finally:
        holder.release()
    assert merge.wait(timeout=120) == 0
    assert not list(out.glob("manifest.*.jsonl"))
    # the other way round: a shard waits while an unsharded writer holds the lock
    holder = Holder(out)
    shard = subprocess.Popen(_warp_cmd(a, out, "--shard", "2/2", "--complete", "zero"), stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        _stderr_until(shard, "waiting for the store lock")
    finally:
        holder.release()
    so, se = shard.communicate(timeout=300)
    assert shard.returncode == 0, se


def test_lock_refuses_a_foreign_directory_before_writing_into_it(tmp_path, two_datasets):
    a, _ = two_datasets
    out = tmp_path / "notastore"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    proc = run_cli(*_warp_cmd(a, out)[1:])
    assert_one_error_line(proc, str(out), "not a vcprep store")
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]  # no lock file left in the user's folder


# -- a full disk names the file ----------------------------------------------------------------------

def _can_mount_tmpfs() -> bool:
    if not shutil.which("unshare"):
        return False
    probe = subprocess.run(["unshare", "-rm", "sh", "-c", "mount -t tmpfs -o size=16k tmpfs /mnt"],
                           capture_output=True)
    return probe.returncode == 0


@pytest.mark.skipif(not _can_mount_tmpfs(), reason="needs unshare -rm to mount a small tmpfs (a real full disk)")
def test_full_disk_error_names_the_file(two_datasets, tmp_path):
    a, _ = two_datasets
    mnt = tmp_path / "small"
    mnt.mkdir()
    warp = " ".join(f"'{x}'" for x in _warp_cmd(a, mnt / "store", "--quiet"))
    script = f"mount -t tmpfs -o size=48k tmpfs '{mnt}' && {warp}"
    proc = subprocess.run(["unshare", "-rm", "sh", "-c", script], capture_output=True, text=True, timeout=300,
                          env={**os.environ})
    assert_one_error_line(proc, f"{mnt / 'store'}/", "No space left on device", "free disk space")
    line = proc.stderr.strip()
    named = line[len("Error: "):].split(": ")[0]
    assert Path(named).parent.parent == mnt / "store" and named.endswith(".png"), line
