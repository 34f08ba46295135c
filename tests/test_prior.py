"""The geometric road prior (vcprep.prior, ``vcprep prior``, ``vcprep figure prior``): against a
direct per-pixel mean over hand-made labels, ignore handled exactly; surrogate labels; files and
bad input."""
from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import run_here, assert_one_error_line, run_cli, write_synthetic_dataset
from vcprep.store import WarpSettings, warp_dataset
from vcprep.dataset import list_dataset
from vcprep.camera import PRESETS
from vcprep.errors import InputError
from vcprep.io import read_image, write_png
from vcprep.labels import get_label_format
from vcprep.prior import (compute_prior, meta_path, read_prior, surrogate_labels, write_prior)
from vcprep.store import Store



CAM = PRESETS["camvid"].resized(0.1)  # 96x72
FMT = get_label_format("camvid")


def _store(root, name, n, scale=0.02, labels=True, prefix=""):
    img, lab = write_synthetic_dataset(root / f"src_{name}", CAM, n=n)
    jobs = list_dataset(img, lab if labels else None, FMT if labels else None, id_prefix=prefix)
    store, _ = warp_dataset(jobs, root / name, WarpSettings(CAM, PRESETS["virtual"], scale, FMT if labels else None,
                                                         progress=False))
    return store


@pytest.fixture(scope="module")
def stores(tmp_path_factory):
    """Two stores of one virtual camera at scale 0.02 (110x56): 3 labelled items, and 2 labelled
    plus 1 unlabelled; every label PNG replaced by a hand-made random 0/1/255 map, with column 0
    ignore in every item (pixels no item labels) and column 1 labelled by exactly one item."""
    root = tmp_path_factory.mktemp("prior")
    a = _store(root, "a", 3)
    b = _store(root, "b", 2)
    _store(root, "b", 1, labels=False, prefix="u_")  # an unlabelled item in the same store
    b = Store.open(root / "b")
    rng = np.random.default_rng(5)
    labels = []
    for s in (a, b):
        for rec in s:
            if not rec.get("label"):
                continue
            w, h = s.store_size
            lab = rng.choice(np.array([0, 1, 255], np.uint8), size=(h, w), p=[0.4, 0.35, 0.25])
            lab[:, 0] = 255
            lab[:, 1] = 255 if labels else 1
            write_png(s.path(rec["label"]), lab, kind="mask")
            labels.append(lab)
    return root, [a, b], labels


def test_prior_equals_direct_mean_with_ignore_excluded(stores):
    _, st, labels = stores
    prior, n_unlabelled = compute_prior(st)
    assert len(labels) == 5 and prior.dtype == np.float32 and prior.shape == (56, 110)
    h, w = prior.shape
    expect = np.zeros((h, w))
    unknown = 0
    for y in range(h):          # the definition, one pixel at a time
        for x in range(w):
            vals = [int(lab[y, x]) for lab in labels if lab[y, x] != 255]
            if vals:
                expect[y, x] = sum(vals) / len(vals)
            else:
                unknown += 1
    assert np.abs(prior - expect).max() < 1e-6
    assert n_unlabelled == unknown and unknown >= h  # column 0, and where all five drew 255
    assert (prior[:, 0] == 0).all() and (prior[:, 1] == 1).all()  # one labelling item says road


def test_cli_writes_npy_png_and_description(stores, tmp_path):
    root, st, _ = stores
    proc = run_here("prior", root / "a", root / "b", "-o", tmp_path / "p.npy")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(tmp_path / "p.npy")
    _, n_unl = compute_prior(st)
    assert f"{n_unl} pixels with no labelled item" in proc.stderr and "5 labelled items" in proc.stderr
    direct, _ = compute_prior(st)
    npy = np.load(tmp_path / "p.npy")
    assert npy.dtype == np.float32 and np.array_equal(npy, direct)
    meta = json.loads(meta_path(tmp_path / "p.npy").read_text())
    assert meta["items"] == 5 and meta["unlabelled_pixels"] == n_unl
    assert meta["store_params"]["scale"] == 0.02 and meta["store_params"]["store_size"] == [110, 56]
    assert run_here("prior", root / "a", root / "b", "-o", tmp_path / "p.png", "-q").returncode == 0
    png = read_image(tmp_path / "p.png", label=True).array
    assert png.dtype == np.uint8 and np.array_equal(png, np.rint(255 * direct.astype(np.float64)).astype(np.uint8))
    back, meta2 = read_prior(tmp_path / "p.png", size=(110, 56))
    assert np.abs(back - direct).max() <= 0.5 / 255 + 1e-7 and meta2 == meta


def test_mixed_stores_are_refused(stores, tmp_path):
    root, _, _ = stores
    other = _store(tmp_path, "coarse", 1, scale=0.025)
    proc = run_here("prior", root / "a", other.root, "-o", tmp_path / "p.npy")
    assert_one_error_line(proc, str(other.root), "scale")
    assert not (tmp_path / "p.npy").exists()
    with pytest.raises(InputError, match="another"):
        compute_prior([root / "a", other.root])


def test_surrogate_labels_thresholds_are_strict():
    p = np.array([[0.0, 0.2499, 0.25, 0.5, 0.75, 0.7501, 1.0]], np.float32)
    assert surrogate_labels(p).tolist() == [[0, 0, 255, 255, 255, 1, 1]]
    assert surrogate_labels(p, lo=0.5, hi=0.5).tolist() == [[0, 0, 0, 255, 1, 1, 1]]
    rng = np.random.default_rng(0)
    assert set(np.unique(surrogate_labels(rng.random((40, 30), np.float32)))) == {0, 1, 255}
    with pytest.raises(InputError):
        surrogate_labels(p, lo=0.8, hi=0.2)


def test_bad_prior_files(tmp_path):
    write_prior(tmp_path / "p.npy", np.full((56, 110), 0.5, np.float32))
    with pytest.raises(InputError, match="prior is 110x56 but the model's store is 120x60"):
        read_prior(tmp_path / "p.npy", size=(120, 60))
    (tmp_path / "junk.npy").write_bytes(b"not numpy")
    np.save(tmp_path / "nan.npy", np.full((4, 4), np.nan, np.float32))
    np.save(tmp_path / "ints.npy", np.zeros((4, 4), np.int32))
    for name, needle in (("junk.npy", "cannot read"), ("nan.npy", "outside [0, 1]"), ("ints.npy", "2-D float"),
                         ("missing.npy", "not found"), ("p.txt", "unknown prior file type")):
        with pytest.raises(InputError, match=needle.replace("[", r"\[").replace("]", r"\]")):
            read_prior(tmp_path / name)
    proc = run_here("prior", tmp_path, "-o", tmp_path / "x.npy")
    assert_one_error_line(proc, "not a vcprep store")


def test_unlabelled_store_and_bad_output(stores, tmp_path):
    root, _, _ = stores
    bare = _store(tmp_path, "bare", 1, labels=False)
    assert_one_error_line(run_here("prior", bare.root, "-o", tmp_path / "p.npy"), "no labelled item")
    assert_one_error_line(run_here("prior", root / "a", "-o", tmp_path / "p.jpg"), "unknown prior file type")


def test_figure_prior_and_help(stores, tmp_path):
    root, _, _ = stores
    proc = run_here("figure", "prior", root / "a", root / "b", "-o", tmp_path / "fig.png", "--width", "440")
    assert proc.returncode == 0, proc.stderr
    fig = read_image(tmp_path / "fig.png").array
    assert fig.shape[1] == 440 and fig.shape[0] > 224 and fig.std() > 20
    assert_one_error_line(run_here("figure", "prior", root / "a", "-o", tmp_path / "f.png", "--lo", "0.9"), "--lo")
    for cmd in (["prior"], ["figure", "prior"]):
        help_ = run_cli(*cmd, "--help")
        assert help_.returncode == 0 and "Example" in help_.stdout
