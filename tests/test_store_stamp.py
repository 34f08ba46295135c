"""Make-friendly stores (issue 52): ``STORE/content.stamp`` changes exactly when the store's content
changes (an item added, rebuilt or removed), and a command that changes nothing writes nothing: no
file of the store (store.json, manifest.jsonl, the lock, part files, PNGs) is rewritten or touched.

Every test runs the real ``vcprep`` command and compares the store's files before and after
(modification time in ns, size, inode: a rewrite by temp file + rename changes the inode)."""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import cv2
import pytest

from conftest import run_cli, write_synthetic_dataset

STAMP = "content.stamp"


@pytest.fixture(scope="module")
def dataset(tmp_path_factory, camvid_half):
    root = tmp_path_factory.mktemp("stamp")
    images, labels = write_synthetic_dataset(root, camvid_half, n=3)
    return images, labels


def _copy(dataset, tmp_path) -> tuple[Path, Path]:
    images, labels = tmp_path / "images", tmp_path / "labels"
    shutil.copytree(dataset[0], images)
    shutil.copytree(dataset[1], labels)
    return images, labels


def _warp(images, labels, out, *extra):
    proc = run_cli("warp", "--camera", "camvid", "--images", images, "--labels", labels, "--label-format", "camvid",
                   "--out", out, "--jobs", "1", *extra)
    assert proc.returncode == 0, proc.stderr
    return proc


def _snapshot(store: Path) -> dict[str, tuple[int, int, int]]:
    """Every file and folder of the store: (mtime ns, size, inode)."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(store):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            st = p.stat()
            out[str(p.relative_to(store))] = (st.st_mtime_ns, st.st_size if p.is_file() else 0, st.st_ino)
    st = store.stat()
    out["."] = (st.st_mtime_ns, 0, st.st_ino)
    return out


def _age_stamp(store: Path) -> None:
    """Set the stamp's time far into the past, so that any later write shows (whatever the clock's tick)."""
    os.utime(store / STAMP, ns=(10**9, 10**9))


def _stamp_changed(store: Path) -> bool:
    return (store / STAMP).stat().st_mtime_ns != 10**9


def test_a_no_op_warp_changes_nothing_on_disk(dataset, tmp_path):
    images, labels = _copy(dataset, tmp_path)
    out = tmp_path / "store"
    _warp(images, labels, out)
    assert (out / STAMP).is_file() and (out / "store.lock").is_file()
    before = _snapshot(out)
    proc = _warp(images, labels, out)
    assert "0 built, 3 up to date" in proc.stderr
    assert _snapshot(out) == before
    # an image touched but not changed: still nothing is written
    os.utime(images / "seq_0001.png")
    _warp(images, labels, out)
    assert _snapshot(out) == before
    # the same for the other writers when they have nothing to do
    proc = run_cli("complete", out, "--method", "projective", "--jobs", "1")
    assert proc.returncode == 0, proc.stderr
    assert "0 completed, 3 up to date" in proc.stderr
    assert _snapshot(out) == before
    for args in (["store", "merge", out], ["store", "verify", out, "--repair"]):
        proc = run_cli(*args)
        assert proc.returncode == 0, proc.stderr
        assert _snapshot(out) == before, args


def test_the_stamp_changes_when_an_item_is_added_rebuilt_or_removed(dataset, tmp_path):
    images, labels = _copy(dataset, tmp_path)
    out = tmp_path / "store"
    _warp(images, labels, out)
    text = (out / STAMP).read_text()

    _age_stamp(out)  # rebuilt: one label edited
    lab = cv2.imread(str(labels / "seq_0001.png"), cv2.IMREAD_UNCHANGED)
    lab[:40] = 3
    cv2.imwrite(str(labels / "seq_0001.png"), lab)
    assert "1 built, 2 up to date" in _warp(images, labels, out).stderr
    assert _stamp_changed(out) and (out / STAMP).read_text() != text
    text = (out / STAMP).read_text()

    _age_stamp(out)  # the same edit undone and redone gives the same content, and the same stamp text
    _warp(images, labels, out)
    assert not _stamp_changed(out)

    _age_stamp(out)  # added: a fourth frame
    shutil.copy(images / "seq_0000.png", images / "seq_0009.png")
    shutil.copy(labels / "seq_0000.png", labels / "seq_0009.png")
    assert "1 built, 3 up to date" in _warp(images, labels, out).stderr
    assert _stamp_changed(out) and (out / STAMP).read_text() != text
    text = (out / STAMP).read_text()

    _age_stamp(out)  # removed: a stored file damaged, verify --repair drops its item
    (out / "images" / "seq_0009.png").write_bytes(b"not a png")
    proc = run_cli("store", "verify", out, "--repair")
    assert "seq_0009" in proc.stdout
    assert _stamp_changed(out) and (out / STAMP).read_text() != text

    _age_stamp(out)  # rebuilt by another completion method
    proc = run_cli("complete", out, "--method", "zero", "--jobs", "1")
    assert proc.returncode == 0, proc.stderr
    assert _stamp_changed(out)


def test_shards_and_merge_keep_the_stamp_true(dataset, tmp_path):
    images, labels = _copy(dataset, tmp_path)
    out = tmp_path / "store"
    for k in (1, 2):
        _warp(images, labels, out, "--shard", f"{k}/2")
    assert (out / STAMP).is_file()
    before = _snapshot(out)
    for k in (1, 2):  # shards with nothing to do write nothing, their part files included
        _warp(images, labels, out, "--shard", f"{k}/2")
    assert _snapshot(out) == before
    _age_stamp(out)  # folding the parts changes the files, not the content: the stamp stays
    proc = run_cli("store", "merge", out)
    assert proc.returncode == 0, proc.stderr
    assert not _stamp_changed(out)
    whole = tmp_path / "whole"  # the same items built unsharded: the same stamp text
    _warp(images, labels, whole)
    assert (whole / STAMP).read_text() == (out / STAMP).read_text()


def test_a_store_without_a_stamp_gets_one_from_its_next_build(dataset, tmp_path):
    """Stores built before the stamp existed: the next build writes it (once)."""
    images, labels = _copy(dataset, tmp_path)
    out = tmp_path / "store"
    _warp(images, labels, out)
    text = (out / STAMP).read_text()
    (out / STAMP).unlink()
    _warp(images, labels, out)
    assert (out / STAMP).read_text() == text
    before = _snapshot(out)
    _warp(images, labels, out)
    assert _snapshot(out) == before
