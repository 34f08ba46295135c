"""Geometry-driven adaptation (vctrain.adapt, ``vctrain adapt``) and the prior as a predictor
(``vctrain predict --prior``), on rendered roads with exactly known masks.

The adaptation scene: a tiny network trained on one camera (CamVid-like) and adapted, without
labels, on another camera (Toronto-like) whose frames swap the source's colours — the road in the
source's grass green, everything else (verge and sky) in its asphalt grey, no kerbs or lane marks
(the kind of shift GeoSeg adapts to: weather, season). A source model that reads colour calls the
whole frame road there. The prior still says where the road is in the virtual camera, so
fine-tuning on its surrogate labels must move the road IoU in the target camera up, by a wide
margin."""
from __future__ import annotations

import json
from dataclasses import fields
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from typer.testing import CliRunner

from conftest import assert_one_error_line, run_cli
from vcprep.store import WarpSettings, warp_dataset
from vcprep.dataset import list_dataset
from vcprep.camera import PRESETS, camera_to_yaml
from vcprep.dataset import Job
from vcprep.errors import InputError
from vcprep.warp import virt_H_src, virtual_at_scale
from vcprep.io import read_image, write_png
from vcprep.labels import get_label_format
from vcprep.prior import compute_prior, prior_meta, write_prior
from vcprep.store import Store
from vcprep.synthetic import RoadScene, render_road
from vctrain.adapt import AdaptSettings, PriorPredictor, adapt, fuse, surrogate_for_item
from vctrain.training import TrainConfig, fit, load_checkpoint
from vctrain.metrics import road_metrics
from vctrain.predict import Predictor, predict_images

torch.set_num_threads(1)
FMT = get_label_format("values:road=1")
SRC = PRESETS["camvid"].resized(0.1)         # 96x72
TGT = PRESETS["toronto2020"].resized(0.1)    # 102x58
SCALE = 0.02                                  # virtual camera store 110x56
runner = CliRunner()


def _render(folder: Path, cam, n: int, seed: int, shifted: bool = False) -> None:
    """``n`` frames (road offset, width and pan drawn from ``seed``) and 0/1 labels; ``shifted``:
    only the road mask is kept, the road painted in the source's grass colours and everything else
    in its asphalt grey, under a fresh smooth texture."""
    (folder / "images").mkdir(parents=True)
    (folder / "labels").mkdir()
    rng = np.random.default_rng(seed)
    for i in range(n):
        scene = RoadScene(offset=float(rng.uniform(-1.5, 1.5)), width=float(rng.uniform(6, 9)),
                          texture_seed=seed * 10 + i)
        img, lab = render_road(cam, scene, pan=float(rng.uniform(-3, 3)))
        if shifted:  # render_road's grass (BGR 40, 120-170, 60) on the road, its asphalt (95-130) elsewhere
            tex = cv2.GaussianBlur(np.random.default_rng((seed, i)).normal(0, 1, lab.shape).astype(np.float32),
                                   (0, 0), 1.5) * 3
            road = np.stack([40 + 5 * tex, 130 + 25 * tex, 60 + 5 * tex], axis=2)
            grey = np.repeat((100 + 20 * tex)[..., None], 3, axis=2)
            img = np.clip(np.where(lab[..., None] == 1, road, grey), 0, 255).astype(np.uint8)
        write_png(folder / "images" / f"s{seed}_{i}.png", img)
        write_png(folder / "labels" / f"s{seed}_{i}.png", lab)


def _train_config(**kw) -> TrainConfig:
    """The paper's SGD recipe where this vctrain has recipes (tiny network, fast)."""
    if "recipe" in {f.name for f in fields(TrainConfig)}:
        kw.setdefault("recipe", "paper")
    return TrainConfig(**kw)


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    """Source store (6 CamVid-camera frames) with its prior; a narrow SegNet fitted on it; the
    target camera's unlabelled adaptation frames and labelled test frames."""
    root = tmp_path_factory.mktemp("adapt")
    _render(root / "src", SRC, 6, seed=0)
    store, _ = warp_dataset(list_dataset(root / "src/images", root / "src/labels", FMT), root / "store",
                            WarpSettings(SRC, PRESETS["virtual"], SCALE, FMT, progress=False))
    prior, n_unl = compute_prior([store])
    write_prior(root / "prior.npy", prior, prior_meta([store], n_unl))
    fit(_train_config(stores=[str(root / "store")], out=str(root / "model.pt"), arch="segnet-narrow", base_width=8,
                      epochs=20, batch_size=2, lr=0.1, val_fraction=0, seed=0, progress=False))
    _render(root / "tgt_train", TGT, 6, seed=3, shifted=True)
    _render(root / "tgt_test", TGT, 4, seed=9, shifted=True)
    (root / "tgt.yaml").write_text(camera_to_yaml(TGT))
    return root


def _target_iou(model: Path, root: Path, out: Path) -> float:
    """Road IoU of ``model`` on the target test frames, in the target camera (warp, infer,
    back-project), against the rendered masks."""
    predict_images(Predictor(model, "cpu"), [root / "tgt_test/images"], out, TGT, progress=False)
    files = sorted((root / "tgt_test/images").iterdir())
    masks = [read_image(out / f"{f.stem}_mask.png", label=True).array // 255 for f in files]
    labels = [read_image(root / "tgt_test/labels" / f.name, label=True).array for f in files]
    return road_metrics(masks, labels)["iou"]


def test_adapting_on_the_target_camera_raises_its_iou(world, tmp_path):
    before = _target_iou(world / "model.pt", world, tmp_path / "before")
    summary = adapt(world / "model.pt", world / "tgt_train/images", TGT, world / "prior.npy", tmp_path / "adapted.pt",
                    AdaptSettings(epochs=16, lr=0.02, progress=False))
    after = _target_iou(tmp_path / "adapted.pt", world, tmp_path / "after")
    print(f"target road IoU: unadapted {before:.3f}, adapted {after:.3f}")
    # measured over source seeds 0-2 with oneDNN on and off: unadapted 0.29-0.49 (0.29 is the road's
    # share of the frame: all road), adapted 0.75-0.84, gain 0.26-0.55
    assert after > 0.7 and after > before + 0.2, (before, after)

    ck = load_checkpoint(tmp_path / "adapted.pt")
    ad = ck["adapted"]
    assert ad["from"] == str(world / "model.pt") and ad["prior"] == str(world / "prior.npy")
    assert (ad["lo"], ad["hi"], ad["combine"]) == (0.25, 0.75, "prior") and len(ad["images"]) == 6
    assert ad["prior_meta"]["items"] == 6 and ck["config"]["init"] == str(world / "model.pt")
    assert ck["data"]["store_params"]["scale"] == SCALE and ck["epoch"] == 16
    assert load_checkpoint(tmp_path / "adapted.last.pt")["adapted"] == ad
    assert summary["adapted"]["label_shares"]["road"] > 0.05

    # the warped target store: the model's virtual camera and scale, surrogate labels recorded
    st = Store.open(tmp_path / "adapted.store")
    assert st.params["scale"] == SCALE and len(st) == 6
    prior = np.load(world / "prior.npy")
    for rec in st:
        lab = read_image(st.path(rec["label"]), label=True).array
        assert rec["label_kind"] == "surrogate" and set(np.unique(lab)) <= {0, 1, 255}
        valid = read_image(st.path(rec["valid"]), label=True).array > 0
        # no completion in the model's store: uncovered pixels ignored, elsewhere the tri-mask
        assert (lab[~valid] == 255).all()
        assert (lab[valid & (prior > 0.75)] == 1).all() and (lab[valid & (prior < 0.25)] == 0).all()
        assert (lab[valid & (prior >= 0.25) & (prior <= 0.75)] == 255).all()


def test_adapt_with_per_frame_calibration(world, tmp_path):
    """``--camera DIR`` (one calibration file per frame): every target frame is warped with its own
    calibrated pose, exactly, and the checkpoint records the folder."""
    import dataclasses

    calib = tmp_path / "calib"
    calib.mkdir()
    frames = sorted((world / "tgt_train/images").glob("*.png"))[:3]
    poses = {}
    for k, f in enumerate(frames):
        cam = dataclasses.replace(TGT, name=f.stem, pan=2.0 * k - 2.0, tilt=1.0 - k)
        (calib / f"{f.stem}.yaml").write_text(camera_to_yaml(cam))
        poses[f.stem] = cam
    args = ["--camera", calib, "--prior", world / "prior.npy", "--out", tmp_path / "a.pt", "--epochs", "1", "--quiet"]
    # a frame without a calibration file is one error line naming it, before any training
    assert_one_error_line(run_cli("adapt", world / "model.pt", "--images", world / "tgt_train/images", *args,
                                  prog="vctrain"), "s3_3.png", "no calibration file")
    assert not (tmp_path / "a.pt").exists()
    images = tmp_path / "images"
    images.mkdir()
    for f in frames:
        (images / f.name).write_bytes(f.read_bytes())
    proc = run_cli("adapt", world / "model.pt", "--images", images, *args, prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    ck = load_checkpoint(tmp_path / "a.pt")
    assert ck["adapted"]["camera"] == {"calibration_folder": str(calib)}
    st = Store.open(tmp_path / "a.store")
    vs = virtual_at_scale(PRESETS["virtual"], SCALE)
    assert len(st) == 3
    for rec in st:
        cam = poses[rec["id"]]
        assert rec["vp_status"] == "calibrated" and rec["label_kind"] == "surrogate"
        H = np.asarray(rec["H"], np.float64).reshape(3, 3)
        np.testing.assert_allclose(H / H[2, 2], virt_H_src(cam, vs, cam.pan, cam.tilt) /
                                   virt_H_src(cam, vs, cam.pan, cam.tilt)[2, 2], rtol=1e-7, atol=1e-7)


def test_adapt_keeps_the_ids_of_the_items_it_is_given(world, tmp_path):
    """A study hands adapt its items (IDD-Lite's ids are '<drive>_<frame>': two drives may hold one
    file name, and the items carry their labels): adapt warps each under its own id, with that id's VP,
    instead of refusing two images of one stem, and reads no label."""
    frames = sorted((world / "tgt_train/images").glob("*.png"))[:2]
    jobs = []
    for drive in ("d1", "d2"):
        (tmp_path / drive).mkdir()
        for f in frames:
            (tmp_path / drive / f.name).write_bytes(f.read_bytes())
            jobs.append(Job(f"{drive}_{f.stem}", tmp_path / drive / f.name, tmp_path / "no-such-label.png"))
    vps = tmp_path / "vps.csv"  # distinct VPs per id: the store must use each id's own
    u0, v0 = TGT.cx, TGT.cy
    vps.write_text("id,u,v\n" + "".join(f"{j.id},{u0 + 2 * k - 3:.3f},{v0 - k:.3f}\n" for k, j in enumerate(jobs)))
    with pytest.raises(InputError, match="two images named"):  # paths alone: ids are stems, and they collide
        adapt(world / "model.pt", [j.image for j in jobs], TGT, world / "prior.npy", tmp_path / "p.pt",
              AdaptSettings(epochs=1, within=str(vps), progress=False))
    adapt(world / "model.pt", jobs, TGT, world / "prior.npy", tmp_path / "a.pt",
          AdaptSettings(epochs=1, within=str(vps), progress=False))
    st = Store.open(tmp_path / "a.store")
    assert sorted(rec["id"] for rec in st) == sorted(j.id for j in jobs)
    assert all(rec["label_kind"] == "surrogate" for rec in st)
    want = {j.id: (u0 + 2 * k - 3, v0 - k) for k, j in enumerate(jobs)}
    for rec in st:
        assert rec["vp"] == pytest.approx(want[rec["id"]], abs=1e-3), rec["id"]
    assert load_checkpoint(tmp_path / "a.pt")["adapted"]["images"] == [str(j.image) for j in jobs]


def test_adapt_self_trains_on_the_models_own_tri_mask(world, tmp_path):
    """``combine='self'`` (the control for what the prior adds): every surrogate label is the
    tri-mask of the source model's own P(road) on that warped target item, computed here by hand
    from the predictor; not the prior's."""
    from vctrain.training import vp_in_store
    from vcprep.prior import surrogate_labels

    _render(tmp_path / "src_more", SRC, 3, seed=5)  # the source camera: the model is sure of road and verge
    summary = adapt(world / "model.pt", tmp_path / "src_more/images", SRC, world / "prior.npy", tmp_path / "s.pt",
                    AdaptSettings(epochs=1, combine="self", progress=False))
    assert summary["adapted"]["combine"] == "self"
    pred, prior = Predictor(world / "model.pt", "cpu"), np.load(world / "prior.npy")
    st = Store.open(tmp_path / "s.store")
    differs = False
    for rec in st:
        pn = pred.road_probability(read_image(st.path(rec["image"])).array, vp_in_store(rec, st))
        lab = read_image(st.path(rec["label"]), label=True).array
        valid = read_image(st.path(rec["valid"]), label=True).array
        want = surrogate_labels(np.asarray(pn, np.float32), 0.25, 0.75)
        want[valid == 0] = 255  # the model was trained without completion: uncovered pixels ignored
        np.testing.assert_array_equal(lab, want)
        differs |= not np.array_equal(lab, surrogate_for_item(prior, 0.25, 0.75, valid))
    assert differs


def test_fuse_and_surrogate_for_item():
    p = np.array([[0.9, 0.9, 0.5, 0.1, 1.0]], np.float32)
    n = np.array([[0.9, 0.1, 0.95, 0.5, 0.0]], np.float32)
    f = fuse(p, n)
    assert f[0, 0] == pytest.approx(0.81 / (0.81 + 0.01)) and f[0, 1] == pytest.approx(0.5)  # cancel
    assert f[0, 2] == pytest.approx(0.95) and f[0, 3] == pytest.approx(0.1) and f[0, 4] == 0.5  # 0/0 -> 0.5
    assert surrogate_for_item(p, 0.25, 0.75, prob=n).tolist() == [[1, 255, 1, 0, 255]]
    valid = np.array([[1, 1, 1, 0, 1]], np.uint8)
    assert surrogate_for_item(p, 0.25, 0.75, valid=valid).tolist() == [[1, 1, 255, 255, 1]]
    # own_only (combine 'self'): the model's prediction alone, the prior unused
    assert surrogate_for_item(p, 0.25, 0.75, prob=n, own_only=True).tolist() == [[1, 0, 1, 255, 0]]
    with pytest.raises(ValueError):
        surrogate_for_item(p, 0.25, 0.75, own_only=True)


def test_adapt_cli_fuse_and_bad_input(world, tmp_path):
    r = runner.invoke(_app(), ["adapt", str(world / "model.pt"), "--images", str(world / "tgt_train/images"),
                               "--camera", str(world / "tgt.yaml"), "--prior", str(world / "prior.npy"),
                               "--combine", "fuse", "--epochs", "1", "--out", str(tmp_path / "f.pt"), "--quiet"])
    assert r.exit_code == 0, r.output
    assert r.stdout.strip() == str(tmp_path / "f.pt")
    assert load_checkpoint(tmp_path / "f.pt")["adapted"]["combine"] == "fuse"

    write_prior(tmp_path / "small.npy", np.full((40, 80), 0.5, np.float32))
    meta = json.loads((world / "prior.npy.json").read_text())
    meta["store_params"]["scale"] = 0.025  # the right size, but its description says another scale
    write_prior(tmp_path / "other.npy", np.load(world / "prior.npy"), meta)
    fit(_train_config(stores=[str(world / "store")], out=str(tmp_path / "resize.pt"), baseline="resize",
                      size=(64, 48), arch="segnet-narrow", base_width=4, epochs=1, batch_size=3, val_fraction=0,
                      progress=False))
    common = ["--images", world / "tgt_train/images", "--camera", world / "tgt.yaml", "--out", tmp_path / "o.pt"]
    cases = [
        (["adapt", world / "model.pt", "--prior", tmp_path / "small.npy", *common],
         ("small.npy", "prior is 80x40 but the model's store is 110x56")),
        (["adapt", world / "model.pt", "--prior", tmp_path / "other.npy", *common],
         ("other.npy", "another scale than the model's (0.025 vs 0.02)")),
        (["adapt", tmp_path / "resize.pt", "--prior", world / "prior.npy", *common],
         ("resize.pt", "no virtual camera")),
        (["adapt", world / "model.pt", "--prior", world / "prior.npy", "--lo", "0.9", *common], ("thresholds",)),
        (["adapt", world / "model.pt", "--prior", world / "prior.npy", "--combine", "vote", *common], ("vote",)),
        (["adapt", world / "model.pt", "--prior", world / "prior.npy", "--epochs", "0", *common], ("epochs 0",)),
    ]
    for args, needles in cases:
        assert_one_error_line(run_cli(*args, prog="vctrain"), *needles)
    assert not (tmp_path / "o.pt").exists()


def _app():
    from vctrain.cli import app

    return app


def test_predict_with_the_prior(world, tmp_path):
    """``vctrain predict --prior``: p_g >= 0.5 back-projected into the images' own camera; checked
    against sampling the prior at H(u, v) pixel by pixel (bilinear, written out here), and as a
    segmentation of the rendered road."""
    _render(tmp_path / "new", SRC, 3, seed=7)
    (tmp_path / "cam.yaml").write_text(camera_to_yaml(SRC))
    proc = run_cli("predict", "--prior", world / "prior.npy", "--camera", tmp_path / "cam.yaml",
                   tmp_path / "new/images", "--out", tmp_path / "pred", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert len(proc.stdout.split()) == 3 and "geometric prior" in proc.stderr
    prior = np.load(world / "prior.npy")
    H = virt_H_src(SRC, virtual_at_scale(PRESETS["virtual"], SCALE))
    w, h = SRC.size
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    q = H @ np.stack([u.ravel(), v.ravel(), np.ones(u.size)])
    x, y = q[0] / q[2], q[1] / q[2]
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    ph, pw = prior.shape
    assert (x0 >= 0).all() and (x0 + 1 < pw).all() and (y0 >= 0).all() and (y0 + 1 < ph).all()
    expect = ((1 - fx) * (1 - fy) * prior[y0, x0] + fx * (1 - fy) * prior[y0, x0 + 1]
              + (1 - fx) * fy * prior[y0 + 1, x0] + fx * fy * prior[y0 + 1, x0 + 1]).reshape(h, w)
    masks, labels = [], []
    for f in sorted((tmp_path / "new/images").iterdir()):
        mask = read_image(tmp_path / "pred" / f"{f.stem}_mask.png", label=True).array
        prob = read_image(tmp_path / "pred" / f"{f.stem}_prob.png", label=True).array
        assert np.abs(prob.astype(float) - 255 * expect).max() <= 1.5
        near = np.abs(expect - 0.5) < 0.01  # bilinear rounding may decide these either way
        assert ((mask == 255) == (expect >= 0.5))[~near].all()
        masks.append(mask // 255)
        labels.append(read_image(tmp_path / "new/labels" / f.name, label=True).array)
    assert road_metrics(masks, labels)["iou"] > 0.6


def test_predict_prior_bad_input(world, tmp_path):
    img = next((world / "tgt_test/images").iterdir())
    np.save(tmp_path / "bare.npy", np.zeros((56, 110), np.float32))  # no description beside it
    cases = [
        (["predict", "--prior", tmp_path / "bare.npy", "--camera", world / "tgt.yaml", img, "-o", tmp_path / "o"],
         ("bare.npy.json",)),
        (["predict", world / "model.pt", "--prior", world / "prior.npy", "--camera", world / "tgt.yaml", img,
          "-o", tmp_path / "o"], ("not both",)),
        (["predict", "--prior", world / "prior.npy", img, "-o", tmp_path / "o"], ("--camera",)),
        (["predict", "--camera", world / "tgt.yaml", "-o", tmp_path / "o"], ("no model",)),
    ]
    for args, needles in cases:
        assert_one_error_line(run_cli(*args, prog="vctrain"), *needles)
    with pytest.raises(Exception, match="bare.npy"):
        PriorPredictor(tmp_path / "bare.npy")


@pytest.mark.parametrize("cmd", ["adapt", "predict"])
def test_help_has_an_example(cmd):
    r = runner.invoke(_app(), [cmd, "--help"])
    assert r.exit_code == 0 and "Example:" in r.stdout
    assert "--prior" in r.stdout


def test_the_prior_keeps_its_rectangle_for_a_wider_camera(world, tmp_path):
    """A prior is an image of the training rectangle: `predict --prior` and `adapt` warp a camera
    wider and steeper than that rectangle into it as it is, while the model's own `predict
    --beyond extend` extends the rectangle for the same frames."""
    from vcprep.camera import Camera

    wide = Camera("wide", (160, 120), 56.0, 56.0, 79.5, 59.5, 1.3, tilt=12.0)  # 110 x 94 deg, 12 deg down
    _render(tmp_path / "new", wide, 2, seed=4)
    (tmp_path / "wide.yaml").write_text(camera_to_yaml(wide))
    prior = np.load(world / "prior.npy")
    common = ["--camera", tmp_path / "wide.yaml", "--within", "none", tmp_path / "new/images"]
    proc = run_cli("predict", "--prior", world / "prior.npy", *common, "--out", tmp_path / "pp", "--keep-store",
                   tmp_path / "kp", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert tuple(Store.open(tmp_path / "kp").store_size) == (prior.shape[1], prior.shape[0])
    proc = run_cli("predict", world / "model.pt", *common, "--out", tmp_path / "pm", "--keep-store", tmp_path / "km",
                   "--beyond", "extend", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    km = Store.open(tmp_path / "km").store_size
    assert km[0] > prior.shape[1] and km[1] > prior.shape[0]
    # a prior never predicts a store of another rectangle (it would sit in the wrong place)
    assert_one_error_line(run_cli("predict", "--prior", world / "prior.npy", "--store", tmp_path / "km", "--out",
                                  tmp_path / "po", prog="vctrain"), "another virtual camera")
    proc = run_cli("adapt", world / "model.pt", "--images", tmp_path / "new/images", "--camera", tmp_path / "wide.yaml",
                   "--within", "none", "--prior", world / "prior.npy", "--out", tmp_path / "a.pt", "--epochs", "1",
                   "--quiet", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert tuple(Store.open(tmp_path / "a.store").store_size) == (prior.shape[1], prior.shape[0])
