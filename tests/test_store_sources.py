"""Stores that do not depend on the working directory (issue 52): a record names its source image,
label and calibration file by absolute, resolved path, so ``store verify``, ``vctrain fit
--baseline resize``, ``vcprep complete`` and a re-warp work from any directory; the same file under
another spelling of its path (relative or absolute, ``a/../a``, a symlinked folder) is the same
source. Stores of older versions (sources relative to the directory they were built from) still
read from there, and their next warp from anywhere records the sources absolute without rebuilding."""
from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

from conftest import assert_one_error_line, run_cli, write_synthetic_dataset


@pytest.fixture
def project(tmp_path, camvid_half) -> Path:
    """``project/data/{images,labels}`` and two working directories, ``project/work`` and ``elsewhere``."""
    root = tmp_path / "project"
    write_synthetic_dataset(root / "data", camvid_half, n=3)
    (root / "work").mkdir()
    (tmp_path / "elsewhere").mkdir()
    return root


def _warp(images, labels, out, cwd, *extra):
    return run_cli("warp", "--camera", "camvid", "--images", images, "--labels", labels, "--label-format", "camvid",
                   "--out", out, "--jobs", "1", *extra, cwd=cwd)


def _records(store: Path) -> list[dict]:
    return [json.loads(line) for line in (store / "manifest.jsonl").read_text().splitlines()]


def _built_from_work(project: Path) -> Path:
    """The store built from ``project/work`` with relative paths, as a user types them."""
    proc = _warp("../data/images", "../data/labels", "stores/mine", project / "work")
    assert proc.returncode == 0, proc.stderr
    return project / "work" / "stores" / "mine"


def test_sources_are_recorded_absolute_and_resolved(project):
    store = _built_from_work(project)
    data = (project / "data").resolve()
    for rec in _records(store):
        assert rec["source"] == str(data / "images" / f"{rec['id']}.png")
        assert rec["label_source"] == str(data / "labels" / f"{rec['id']}.png")


def test_verify_fit_and_complete_work_from_another_directory(project, tmp_path):
    store = _built_from_work(project)
    elsewhere = tmp_path / "elsewhere"
    proc = run_cli("store", "verify", store, cwd=elsewhere)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "source missing" not in proc.stdout
    proc = run_cli("fit", store, "--baseline", "resize", "--size", "64x48", "--epochs", "1", "--val-fraction", "0",
                   "--out", tmp_path / "resize.pt", "--quiet", prog="vctrain", cwd=elsewhere)
    assert proc.returncode == 0, proc.stderr
    proc = run_cli("complete", store, "--method", "zero", "--jobs", "1", cwd=elsewhere)
    assert proc.returncode == 0, proc.stderr
    assert "3 completed" in proc.stderr


@pytest.mark.parametrize("spelling", ["absolute", "dotdot", "symlink", "relative-from-elsewhere"])
def test_the_same_file_under_another_spelling_is_the_same_source(project, tmp_path, spelling):
    store = _built_from_work(project)
    before = _records(store)
    data, cwd = project / "data", tmp_path / "elsewhere"
    if spelling == "absolute":
        images, labels = data / "images", data / "labels"
    elif spelling == "dotdot":
        images, labels = data / "images" / ".." / "images", data / "labels" / ".." / ".." / "data" / "labels"
    elif spelling == "symlink":
        (tmp_path / "link").symlink_to(data, target_is_directory=True)
        images, labels = tmp_path / "link" / "images", tmp_path / "link" / "labels"
    else:
        images, labels = Path("../project/data/images"), Path("../project/data/labels")
    proc = _warp(images, labels, store, cwd)
    assert proc.returncode == 0, proc.stderr
    assert "0 built, 3 up to date" in proc.stderr
    assert _records(store) == before


def test_another_file_under_the_same_id_is_still_refused(project, tmp_path):
    store = _built_from_work(project)
    other = tmp_path / "other"
    shutil.copytree(project / "data", other)
    proc = _warp(other / "images", other / "labels", store, tmp_path / "elsewhere")
    assert_one_error_line(proc, "already holds another source", "--id-prefix")


def _make_legacy(store: Path, relative_to: Path) -> None:
    """Rewrite the records as versions before issue 52 wrote them: paths relative to the build's cwd."""
    recs = _records(store)
    for rec in recs:
        for key in ("source", "label_source"):
            rec[key] = os.path.relpath(os.path.normpath(relative_to / rec[key]), relative_to)
    (store / "manifest.jsonl").write_text("".join(json.dumps(r, separators=(",", ":")) + "\n" for r in recs))


def test_an_older_store_reads_from_its_directory_and_is_rerecorded_absolute(project, tmp_path):
    store = _built_from_work(project)
    absolute = _records(store)
    work = project / "work"
    _make_legacy(store, work)
    assert _records(store)[0]["source"] == "../data/images/seq_0000.png"
    proc = run_cli("store", "verify", store, cwd=work)  # read from where it was built: as before
    assert proc.returncode == 0, proc.stdout + proc.stderr
    proc = run_cli("store", "verify", store, cwd=tmp_path / "elsewhere")  # from elsewhere: missing, and why
    assert proc.returncode == 1 and "re-run its vcprep warp once" in proc.stdout, proc.stdout
    # its next warp, from another directory: nothing rebuilt, the sources recorded absolute
    data = project / "data"
    proc = _warp(data / "images", data / "labels", store, tmp_path / "elsewhere")
    assert proc.returncode == 0, proc.stderr
    assert "0 built, 3 up to date" in proc.stderr
    assert _records(store) == absolute
    proc = run_cli("store", "verify", store, cwd=tmp_path / "elsewhere")
    assert proc.returncode == 0, proc.stdout + proc.stderr
