"""vctrain crossval: conditions prior, adapt and adapt-fuse (adapt-self: tests/test_adapt.py)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from vcprep.store import Store

from conftest import assert_one_error_line, run_cli
from studies import GEO_CONDS, _geo_study, _mixed_study, _rows


@pytest.fixture(scope="module")
def geo_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("crossval_geo")
    study = _geo_study(root / "data")
    out = root / "out"
    proc = run_cli("crossval", study, "--out", out, "--json", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    return study, out, proc


def _own_prior(stores: list[Path]):
    """p_g by hand: per store pixel, (labels == 1) / (labels != 255) over the stores' label PNGs."""
    import cv2
    import numpy as np

    road = known = 0
    for s in map(Store.open, stores):
        for rec in s:
            lab = cv2.imread(str(s.path(rec["label"])), cv2.IMREAD_UNCHANGED)
            road, known = road + (lab == 1), known + (lab != 255)
    return np.where(known > 0, road / np.maximum(known, 1), 0.0).astype(np.float32)


def test_prior_condition_equals_an_independent_computation(geo_run):
    import cv2
    import numpy as np

    _, out, _ = geo_run
    rows = {(r["heldout"], r["condition"]): r for r in _rows(out)}
    assert set(rows) == {(h, c) for h in ("kitti", "cityscapes", "camvid2") for c in GEO_CONDS}
    cases = {"kitti": ["camvid"], "cityscapes": ["camvid", "kitti"], "camvid2": ["camvid", "kitti"]}
    data = out.parent / "data"
    for held, train in cases.items():
        row = rows[held, "prior"]
        assert row["train_datasets"] == train and row["epochs"] == 0
        prior = _own_prior([out / "stores" / t / "train" / "within" for t in train])
        tp = fp = fn = 0
        # per-image estimated VPs, as the paper; in the training rectangle as it is (as predict --prior warps):
        # the within test store's own where no frame reaches past it, else its -fixed twin
        fixed = out / "stores" / held / "test" / "within-fixed"
        test = Store.open(fixed if fixed.exists() else out / "stores" / held / "test" / "within")
        assert test.params["virtual"] == Store.open(out / "stores" / train[0] / "train" / "within").params["virtual"]
        assert {r["vp_status"] for r in test} <= {"accepted", "fallback"}
        for rec in test:
            w, h = rec["size"]
            H = np.asarray(rec["H"], np.float64).reshape(3, 3)          # source pixel -> store pixel
            p = cv2.warpPerspective(prior, H, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                    borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            raw = cv2.imread(str(data / f"{held}_test" / "labels" / f"{rec['id']}.png"), cv2.IMREAD_UNCHANGED)
            pred, road, keep = p >= 0.5, raw == 3, raw != 11            # camvid ids: 3 road, 11 void
            tp += np.count_nonzero(pred & road & keep)
            fp += np.count_nonzero(pred & ~road & keep)
            fn += np.count_nonzero(~pred & road & keep)
        assert row["test_items"] == len(test)
        assert row["iou"] == pytest.approx(tp / (tp + fp + fn), abs=1e-4)
        run = "kitti" if held == "kitti" else "_all"
        assert not (out / "runs" / run / "prior" / "model.pt").exists()       # no training
        saved = np.load(out / "runs" / run / "prior" / "prior.npy")
        assert np.abs(saved - prior).max() < 1e-6


def test_prior_and_adapt_put_every_store_in_one_rectangle(geo_run):
    """The prior is an image of the training rectangle: a study with prior/adapt that does not set
    'canvas' gets the shared rectangle (said in study.json), every training store and every store the
    prior is scored on the same size; a model's test store (within, for adapt) is that rectangle,
    extended only where a frame at its pose reaches past it (as vctrain predict extends it)."""
    from vcprep.camera import same_camera_other_canvas

    _, out = geo_run[:2]
    assert json.loads((out / "study.json").read_text())["canvas"] == "shared"
    stores = {p: Store.open(p) for p in (out / "stores").glob("*/*/*")}
    prior = [p for p in stores if p.parent.name == "train" or p.name == "within-fixed" or
             (p.parent.name == "test" and not (p.parent / "within-fixed").exists())]
    assert len({tuple(stores[p].store_size) for p in prior}) == 1
    one = stores[prior[0]].params["virtual"]
    assert all(same_camera_other_canvas(s.params["virtual"], one) for s in stores.values())


def test_adapt_reuses_the_within_model_and_never_reads_test_labels(geo_run):
    import numpy as np
    import torch

    from vcprep.io import read_image
    from vcprep.prior import surrogate_labels

    _, out, proc = geo_run
    # one within model per run, trained once (adapt's source); no other training
    assert proc.stderr.count("training on") == 2 and proc.stderr.count("within: training on") == 2
    for run, targets in (("kitti", {"kitti": out / "runs" / "kitti" / "adapt"}),
                         ("_all", {t: out / "runs" / "_all" / "adapt" / t for t in ("cityscapes", "camvid2")})):
        src = out / "runs" / run / "within" / "model.pt"
        assert json.loads((out / "runs" / run / "within" / "train.json").read_text())["train_items"] > 0
        prior = np.load(out / "runs" / run / "adapt" / "prior.npy")
        for ds, adir in targets.items():
            ck = torch.load(adir / "model.pt", map_location="cpu", weights_only=False)
            assert ck["adapted"]["from"] == str(src) and ck["config"]["init"] == str(src)
            rec = json.loads((adir / "adapt.json").read_text())
            assert rec["target"] == ("unlabelled" if ds == "camvid2" else "test")
            store = Store.open(adir / "target.store")
            assert ck["config"]["stores"] == [str(store.root)]
            folder = out.parent / "data" / (f"{ds}_unlabelled" if ds == "camvid2" else f"{ds}_test") / "images"
            assert len(store) == rec["target_items"] > 0
            for item in store:
                assert Path(item["source"]).parent == folder and not item.get("label_source")
                assert item["label_kind"] == "surrogate"
                lab = read_image(store.path(item["label"]), label=True).array
                # the labels trained on are the prior's tri-mask, the same for every image: no test label
                assert np.array_equal(lab, surrogate_labels(prior, 0.25, 0.75))
            row = json.loads(((out / "runs" / run / "adapt") /
                              ("result.json" if ds == run else f"result-{ds}.json")).read_text())
            assert row["adapt_target"] == rec["target"] and row["train_datasets"] == (
                ["camvid"] if run == "kitti" else ["camvid", "kitti"])
            assert row["test_items"] == {"kitti": 2, "cityscapes": 1, "camvid2": 3}[ds]


def test_prior_and_adapt_resume_and_share_the_within_model(geo_run, tmp_path):
    import shutil

    study, out, proc = geo_run
    copy = tmp_path / "out"
    shutil.copytree(out, copy)
    models = sorted(copy.glob("runs/**/model.pt"))
    assert len(models) == 5                          # 2 within + 3 adapted
    before = {p: p.stat().st_mtime_ns for p in models}
    lost = copy / "runs" / "_all" / "adapt" / "result-camvid2.json"
    iou = json.loads(lost.read_text())["iou"]
    lost.unlink()
    again = run_cli("crossval", study, "--out", copy, "--conditions", "within,prior,adapt", "--json", prog="vctrain")
    assert again.returncode == 0, again.stderr
    assert "training on" not in again.stderr and "adapting" not in again.stderr
    assert again.stderr.count("model trained earlier") == 3      # within (2 runs) and adapt's source for camvid2
    assert "adapted earlier" in again.stderr and again.stderr.count("done earlier") == 5
    assert {p: p.stat().st_mtime_ns for p in models} == before
    assert json.loads(lost.read_text())["iou"] == pytest.approx(iou)
    summary = json.loads(again.stdout.strip().splitlines()[-1])
    assert list(summary) == ["within", "prior", "adapt"]
    assert summary["prior"] == pytest.approx(json.loads(proc.stdout.strip().splitlines()[-1])["prior"])


def test_adapt_fuse_fuses_the_prior_with_the_within_models_own_prediction(geo_run, tmp_path):
    """Condition adapt-fuse: the same within model (no training), adapted with surrogate labels
    = tri-mask of p_g p_n / (p_g p_n + (1 - p_g)(1 - p_n)), p_n the within model's own P(road)
    on each target image, computed here by hand from the predictor."""
    import shutil

    import numpy as np
    import torch

    from vcprep.io import read_image
    from vcprep.prior import surrogate_labels
    from vctrain.training import vp_in_store
    from vctrain.predict import Predictor

    study, out, proc = geo_run
    copy = tmp_path / "out"
    shutil.copytree(out, copy)
    again = run_cli("crossval", study, "--out", copy, "--conditions", "within,adapt-fuse", "--json", prog="vctrain")
    assert again.returncode == 0, again.stderr
    assert "training on" not in again.stderr and again.stderr.count("adapting the within model") == 3
    summary = json.loads(again.stdout.strip().splitlines()[-1])
    assert list(summary) == ["within", "adapt-fuse"]
    for run, ds in (("kitti", "kitti"), ("_all", "cityscapes"), ("_all", "camvid2")):
        adir = copy / "runs" / run / "adapt-fuse" / ("" if ds == run else ds)
        src = copy / "runs" / run / "within" / "model.pt"
        ck = torch.load(adir / "model.pt", map_location="cpu", weights_only=False)
        assert ck["adapted"]["combine"] == "fuse" and ck["adapted"]["from"] == str(src)
        prior = np.load(copy / "runs" / run / "adapt-fuse" / "prior.npy")
        pred = Predictor(src, "cpu")
        store = Store.open(adir / "target.store")
        differs = False
        for item in store:
            pn = pred.road_probability(read_image(store.path(item["image"])).array, vp_in_store(item, store))
            a, b = prior.astype(np.float64) * pn, (1 - prior.astype(np.float64)) * (1 - pn)
            fused = np.divide(a, a + b, out=np.full(a.shape, 0.5), where=(a + b) > 0)
            lab = read_image(store.path(item["label"]), label=True).array
            np.testing.assert_array_equal(lab, surrogate_labels(fused.astype(np.float32), 0.25, 0.75))
            differs |= not np.array_equal(lab, surrogate_labels(prior, 0.25, 0.75))
        assert differs  # the network's own evidence changed the labels somewhere
    row = json.loads((copy / "runs" / "_all" / "adapt-fuse" / "result-cityscapes.json").read_text())
    assert row["condition"] == "adapt-fuse" and row["train_datasets"] == ["camvid", "kitti"]


@pytest.mark.parametrize("edit, needle", [
    (lambda d, root: (root / "empty").mkdir() or d["datasets"][3].update(unlabelled={"images": "empty"}),
     "dataset 'camvid2' unlabelled: no images"),
    (lambda d, root: d["datasets"][0].update(unlabelled={"images": "camvid_train/images"}),
     "'unlabelled' split would never be used"),
    (lambda d, root: d["datasets"][3].update(unlabelled={"images": "camvid2_test/images", "labels": "x"}),
     "unknown key 'labels' in dataset 'camvid2' unlabelled"),
])
def test_bad_adapt_input_gives_one_error_line(tmp_path, edit, needle):
    root = tmp_path / "data"
    study = _mixed_study(root)
    d = yaml.safe_load(study.read_text())
    edit(d, root)
    d["conditions"] = ["adapt"]
    study.write_text(yaml.safe_dump(d))
    out = tmp_path / "out"
    proc = run_cli("crossval", study, "--out", out, prog="vctrain")
    assert_one_error_line(proc, needle)
    assert not out.exists()
