"""vctrain: metrics against hand-computed cases, model/data units, and a tiny end-to-end run on a
synthetic store (fit -> checkpoint -> predict on another camera -> eval), plus CLI errors."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from typer.testing import CliRunner

from vcprep.store import WarpSettings, warp_dataset
from vcprep.dataset import list_dataset
from vcprep.camera import PRESETS
from vcprep.errors import InputError
from vcprep.io import read_image, write_png
from vcprep.labels import get_label_format
from vcprep.synthetic import RoadScene, render_road
from vctrain.training import (RECIPES, RoadDataset, Sample, TrainConfig, evaluate, fit, get_lr, load_checkpoint,
                              median_frequency_weights, model_from_checkpoint, resolve_recipe, to_input, vp_proximity)
from vctrain.cli import app
from vctrain.metrics import KittiMetrics, RoadMetrics, confusion, kitti_metrics, road_metrics
from vctrain.networks import ModelArgs, SegNet, model_args_for

torch.set_num_threads(1)
FMT = "values:road=1"  # the synthetic labels: 0 not road, 1 road
runner = CliRunner()


# -- metrics -------------------------------------------------------------------------------------
def test_confusion_ignores_255():
    label = np.array([[1, 1, 0, 0], [255, 255, 1, 0]], np.uint8)
    pred = np.array([[1, 0, 1, 0], [1, 0, 1, 1]], np.uint8)
    assert confusion(pred, label) == (2, 2, 1, 1)  # TP, FP, FN, TN; the two ignore pixels never count


def test_road_metrics_hand_computed():
    # image A: TP 2 FP 2 FN 1 (IoU 2/5); image B: TP 1 FP 0 FN 1 (IoU 1/2); image C: no road anywhere
    a_l = np.array([[1, 1, 0, 0], [255, 255, 1, 0]], np.uint8)
    a_p = np.array([[1, 0, 1, 0], [1, 0, 1, 1]], np.uint8)
    b_l = np.array([[1, 1]], np.uint8)
    b_p = np.array([[1, 0]], np.uint8)
    c_l = np.zeros((2, 2), np.uint8)
    c_p = np.zeros((2, 2), np.uint8)
    m = road_metrics([a_p, b_p, c_p], [a_l, b_l, c_l])
    assert m["iou"] == pytest.approx(3 / 7)                  # ΣTP / Σ(TP+FP+FN) = 3 / (3+2+2)
    assert m["mean_image_iou"] == pytest.approx((2 / 5 + 1 / 2) / 2)  # C (union 0) left out
    assert m["precision"] == pytest.approx(3 / 5)            # 3 / (3+2)
    assert m["recall"] == pytest.approx(3 / 5)               # 3 / (3+2)
    assert m["f1"] == pytest.approx(0.6)


def test_road_metrics_empty_and_shape_mismatch():
    assert RoadMetrics().result()["iou"] == 0.0
    from vcprep.errors import InputError

    with pytest.raises(InputError):
        confusion(np.zeros((2, 3)), np.zeros((3, 2), np.uint8))


def test_kitti_metrics_hand_computed():
    # 2 road pixels (p 200, 100), 2 not road (p 150, 50), 1 ignore (p 255)
    prob = np.array([[200, 100, 150, 50, 255]], np.uint8)
    label = np.array([[1, 1, 0, 0, 255]], np.uint8)
    k = kitti_metrics([prob], [label])
    # thresholds (road iff p >= k): k<=50: P 1/2 R 1; 51..100: P 2/3 R 1 (F 0.8);
    # 101..150: P 1/2 R 1/2; 151..200: P 1 R 1/2 (F 2/3); > 200: P = R = 0 (dropped)
    assert k["maxf"] == pytest.approx(0.8)
    assert k["precision"] == pytest.approx(2 / 3)
    assert k["recall"] == pytest.approx(1.0)
    assert k["fpr"] == pytest.approx(1 / 2)      # FP 1 / (FP 1 + TN 1)
    assert k["fnr"] == pytest.approx(0.0)
    assert k["threshold"] == pytest.approx(51 / 255)  # the first threshold of the best plateau
    # 11-point AP: recall levels 0..0.5 -> max precision 1; 0.6..1.0 -> 2/3
    assert k["ap"] == pytest.approx((6 * 1.0 + 5 * (2 / 3)) / 11)


def test_kitti_perfect_and_accumulation():
    label = np.array([[1, 0], [1, 0]], np.uint8)
    prob = np.array([[255, 0], [230, 3]], np.uint8)
    m = KittiMetrics()
    m.add(prob, label)
    m.add(prob, label)
    r = m.result()
    assert r["maxf"] == pytest.approx(1.0) and r["ap"] == pytest.approx(1.0) and r["fpr"] == 0.0


# -- model and data --------------------------------------------------------------------------------
def test_segnet_shapes_any_size_and_extra_channel():
    net = SegNet(ModelArgs(arch="segnet-narrow", base_width=4, in_channels=4)).eval()
    with torch.no_grad():
        assert net(torch.zeros(1, 4, 37, 70)).shape == (1, 2, 37, 70)
    assert len([m for m in net.encoders.modules() if isinstance(m, torch.nn.Conv2d)]) == 13  # VGG16
    assert model_args_for("segnet").base_width == 64 and model_args_for("segnet-narrow").base_width == 16


def test_vp_proximity_definition():
    m = vp_proximity((5, 3), (2.0, 1.0))
    assert m[1, 2] == pytest.approx(1.0)
    assert m[0, 0] == pytest.approx(1 - max(2 / 5, 1 / 3))
    assert m[2, 4] == pytest.approx(1 - max(2 / 5, 1 / 3))
    # float32 whatever the VP's type: the scale augmentation moves the VP by a float64 affine map
    assert m.dtype == np.float32 and vp_proximity((5, 3), (np.float64(2.0), np.float64(1.0))).dtype == np.float32


def test_median_frequency_weights():
    w = median_frequency_weights(np.array([0.8, 0.2]))
    assert w == pytest.approx([0.5 / 0.8, 0.5 / 0.2])


def test_poly_schedule():
    cfg = TrainConfig(lr=0.01, schedule="poly")
    assert get_lr(0, 100, cfg) == pytest.approx(0.01)
    assert get_lr(100, 100, cfg) == 0.0
    assert get_lr(50, 100, cfg) == pytest.approx(0.01 * 0.5 ** 0.9)


def test_cosine_schedule_warms_up_then_decays():
    cfg = TrainConfig(lr=0.01, schedule="cosine")
    assert get_lr(0, 1000, cfg) == pytest.approx(0.01 / 30)           # warm-up: 3 % of 1000 steps
    assert get_lr(29, 1000, cfg) == pytest.approx(0.01)
    assert get_lr(30, 1000, cfg) == pytest.approx(0.01)                 # the peak
    mid = 30 + (1000 - 30) / 2
    assert get_lr(int(mid), 1000, cfg) == pytest.approx(0.005, rel=1e-2)
    assert get_lr(1000, 1000, cfg) == pytest.approx(0.0, abs=1e-12)
    lrs = [get_lr(i, 1000, cfg) for i in range(30, 1001)]
    assert all(a >= b for a, b in zip(lrs, lrs[1:]))                    # monotone after the warm-up
    for total in (120, 7, 1):  # a warm-up of a fraction of steps (3.6 of 120) never overshoots the peak
        assert max(get_lr(i, total, cfg) for i in range(total + 1)) == pytest.approx(0.01)


def test_recipes_fill_only_unset_fields():
    cpu = resolve_recipe(TrainConfig(recipe="cpu"))
    assert (cpu.arch, cpu.optimizer, cpu.schedule, cpu.hflip) == ("resfpn", "adamw", "cosine", True)
    paper = resolve_recipe(TrainConfig(recipe="paper"))
    assert (paper.arch, paper.optimizer, paper.lr, paper.weight_decay, paper.batch_size, paper.schedule) == \
        ("segnet", "sgd", 0.005, 0.0005, 8, "poly")
    assert paper.scale_aug == paper.color_aug == 0 and paper.hflip is False
    mixed = resolve_recipe(TrainConfig(recipe="paper", lr=0.01, hflip=True, arch="segnet-narrow"))
    assert (mixed.lr, mixed.hflip, mixed.arch, mixed.optimizer) == (0.01, True, "segnet-narrow", "sgd")
    assert resolve_recipe(TrainConfig(device="cpu")).recipe == "cpu"  # no GPU -> the cpu recipe
    # on a GPU too (issue 44: the measured recipe wherever it runs, not the paper's unmeasured segnet)
    on_gpu = resolve_recipe(TrainConfig(device="cuda"), torch.device("cuda"))
    assert (on_gpu.recipe, on_gpu.arch, on_gpu.optimizer) == ("cpu", "resfpn", "adamw")
    assert cpu.balance == paper.balance == "items"
    multi = resolve_recipe(TrainConfig(recipe="multicamera"))
    assert (multi.arch, multi.pretrained, multi.balance, multi.shading_aug, multi.epochs) == \
        ("lite0fpn", True, "datasets", 0.4, 30)
    assert resolve_recipe(TrainConfig(recipe="multicamera", balance="items", arch="resfpn")).pretrained is False
    for bad in (dict(recipe="gpu"), dict(optimizer="adam"), dict(schedule="step"), dict(lr=0.0),
                dict(scale_aug=-0.1), dict(epochs=0), dict(balance="frames")):
        with pytest.raises(InputError):
            resolve_recipe(TrainConfig(**{"recipe": "cpu", **bad}))


def test_scale_augmentation_is_about_the_vp(tmp_path):
    """A random scale about the VP moves every labelled pixel radially from the VP: a road
    wedge with its apex at the VP stays a wedge with the same apex (up to the shift, here 0)."""
    w, h, vp = 80, 48, (30.0, 12.0)
    yy, xx = np.mgrid[0:h, 0:w]
    wedge = (yy > vp[1]) & (np.abs(xx - vp[0]) < 0.8 * (yy - vp[1]))  # invariant under scaling about vp
    img = np.where(wedge[..., None], 200, 40).astype(np.uint8).repeat(3, axis=2)
    write_png(tmp_path / "i.png", img)
    write_png(tmp_path / "l.png", wedge.astype(np.uint8))
    ds = RoadDataset([Sample("i", tmp_path / "i.png", tmp_path / "l.png", None, vp)], (w, h), scale_aug=0.5,
                     vp_channel=True)
    torch.manual_seed(3)
    for _ in range(8):
        x, y = ds[0]
        y = y.numpy()
        known = y != 255
        # far from the wedge's edges, labels are unchanged by any scale about the VP
        inner = (yy > vp[1] + 2) & (np.abs(np.abs(xx - vp[0]) - 0.8 * (yy - vp[1])) > 2)
        assert known[inner].mean() > 0.3  # (a shrink by 1/1.5 leaves ~40 % known)
        assert np.array_equal(y[inner & known], wedge[inner & known].astype(np.int64))
        assert int(x[3].flatten().argmax()) == int(round(vp[1])) * w + int(round(vp[0]))  # VP did not move
    # a scale < 1 leaves ignore (not a guess) where no source pixel lands
    ds2 = RoadDataset([Sample("i", tmp_path / "i.png", tmp_path / "l.png", None, (0.0, 0.0))], (w, h), scale_aug=1.0)
    shrunk = [(ds2[0][1].numpy() == 255).mean() for _ in range(20)]
    assert max(shrunk) > 0.2 and min(shrunk) == 0.0


def test_photometric_jitter_keeps_labels_and_range(tmp_path):
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (24, 32, 3), dtype=np.uint8)
    lab = (rng.random((24, 32)) > 0.5).astype(np.uint8)
    write_png(tmp_path / "i.png", img)
    write_png(tmp_path / "l.png", lab)
    ds = RoadDataset([Sample("i", tmp_path / "i.png", tmp_path / "l.png")], (32, 24), color_aug=0.3)
    torch.manual_seed(0)
    xs = []
    for _ in range(6):
        x, y = ds[0]
        assert np.array_equal(y.numpy(), lab) and x.min() >= -1 and x.max() <= 1
        xs.append(x.numpy())
    assert np.std([v.mean() for v in xs]) > 0.01  # it does change the image


def test_photometric_table_lookup_equals_the_per_pixel_formula():
    """The 8-bit fast path (one 256 x 3 table) gives, per draw, the module docstring's jitter
    computed pixel by pixel in float64: gamma, contrast about the image mean, brightness x gain."""
    rng = np.random.default_rng(1)
    ds = RoadDataset([], (40, 30), color_aug=0.3)
    for k in range(10):
        img = rng.integers(0, 256, (30, 40, 3), dtype=np.uint8)
        torch.manual_seed(k)
        bright, contrast, gain, gamma = ds._photometric_draw()
        v = (img.astype(np.float64) / 255.0) ** gamma
        want = np.clip(((v - v.mean()) * contrast + v.mean()) * bright * gain.astype(np.float64), 0, 1) * 2 - 1
        torch.manual_seed(k)
        got = ds._photometric_u8(img)
        assert got.shape == (3, 30, 40) and got.dtype == np.float32
        np.testing.assert_allclose(got, want.transpose(2, 0, 1), atol=1e-5)
        assert np.abs(got - to_input(img)).max() > 0.01  # the draw does change the image


def test_hflip_moves_vp_channel(tmp_path):
    img = np.zeros((32, 40, 3), np.uint8)
    lab = np.zeros((32, 40), np.uint8)
    lab[:, :10] = 1
    write_png(tmp_path / "i.png", img)
    write_png(tmp_path / "l.png", lab)
    ds = RoadDataset([Sample("i", tmp_path / "i.png", tmp_path / "l.png", None, (5.0, 8.0))], (40, 32),
                     hflip=True, vp_channel=True)
    torch.manual_seed(0)
    seen = set()
    for _ in range(12):
        x, y = ds[0]
        assert x.shape == (4, 32, 40)
        flipped = bool(y[0, -1] == 1)
        seen.add(flipped)
        col = int(x[3, 8].argmax())
        assert col == (34 if flipped else 5)  # the VP follows the flip
    assert seen == {True, False}


def _coordinate_item(tmp_path, w: int, h: int) -> Sample:
    """An image and label whose pixel values encode their own (x, y): any window is identifiable."""
    yy, xx = np.mgrid[0:h, 0:w]
    img = np.stack([xx * 3, yy * 5, (xx + yy) % 256], axis=2).astype(np.uint8)
    write_png(tmp_path / "c.png", img)
    write_png(tmp_path / "cl.png", ((xx + 2 * yy) % 2).astype(np.uint8))
    return Sample("c", tmp_path / "c.png", tmp_path / "cl.png", None, (31.0, 9.0))


@pytest.mark.parametrize("affine", [False, True])
def test_random_crop_is_an_exact_window_of_the_working_image(tmp_path, affine):
    """--crop: each training item is a (cw, ch) window of the working image at a random position
    inside it, the VP channel is the window of the whole image's map (normalised by the whole
    size), and positions cover the image. With the affine augmentation drawn at a vanishing
    strength the window (one composed warp) must be the same exact window."""
    w, h, cw, ch = 64, 40, 40, 24
    sample = _coordinate_item(tmp_path, w, h)
    eps = 1e-9 if affine else 0.0
    full = RoadDataset([sample], (w, h), vp_channel=True)
    ds = RoadDataset([sample], (w, h), vp_channel=True, crop=(cw, ch), scale_aug=eps, shift_aug=eps)
    x_full, y_full = full[0]
    torch.manual_seed(5)
    origins = set()
    for _ in range(40):
        x, y = ds[0]
        assert x.shape == (4, ch, cw) and y.shape == (ch, cw)
        # the image's first two channels give the window's origin
        x0 = int(round((x[0, 0, 0].item() + 1) / 2 * 255 / 3))
        y0 = int(round((x[1, 0, 0].item() + 1) / 2 * 255 / 5))
        assert 0 <= x0 <= w - cw and 0 <= y0 <= h - ch
        origins.add((x0, y0))
        np.testing.assert_allclose(x.numpy(), x_full[:, y0:y0 + ch, x0:x0 + cw].numpy(), atol=1e-4)
        assert torch.equal(y, y_full[y0:y0 + ch, x0:x0 + cw])
    xs, ys = {o[0] for o in origins}, {o[1] for o in origins}
    assert len(origins) > 20 and min(xs) <= 3 and max(xs) >= w - cw - 3 and min(ys) <= 2 and max(ys) >= h - ch - 2


def test_crop_size_from_shares_or_pixels():
    from vctrain.training import crop_size

    assert crop_size(None, (480, 360)) == (480, 360)
    assert crop_size(2 / 3, (480, 360)) == (320, 240)
    assert crop_size(1.0, (99, 50)) == (99, 50)
    assert crop_size((320, 200), (480, 360)) == (320, 200)
    assert crop_size((0.5, 1.0), (480, 360)) == (240, 360)  # shares of width and height: full-height windows
    assert crop_size([0.4444, 1.0], (749, 231)) == (333, 231)
    from vctrain.cli import _parse_crop

    assert [_parse_crop(t) for t in ("320x240", "0.67", "0.5x1", "0.5x1.0")] == [(320, 240), 0.67, (0.5, 1.0),
                                                                              (0.5, 1.0)]
    with pytest.raises(InputError):
        _parse_crop("wide")
    for bad in (0.0, 1.5, (500, 200), (20, 20), (0.5, 1.5)):
        with pytest.raises(InputError):
            crop_size(bad, (480, 360))
    # a share never makes a side below MIN_SIDE (32), so the cpu recipe's window works on any store
    assert crop_size(0.05, (480, 360)) == (32, 32) and crop_size((0.05, 1.0), (480, 360)) == (32, 360)
    assert crop_size(RECIPES["cpu"]["crop"], (64, 40)) == (32, 40)
    assert crop_size(RECIPES["cpu"]["crop"], (638, 271)) == (284, 271)


# -- end to end on a synthetic store ----------------------------------------------------------------
def _render_set(folder: Path, cam, n: int, seed: int = 0):
    (folder / "images").mkdir(parents=True)
    (folder / "labels").mkdir()
    rng = np.random.default_rng(seed)
    for i in range(n):
        scene = RoadScene(offset=float(rng.uniform(-2, 2)), width=float(rng.uniform(6, 10)), texture_seed=seed * 10 + i)
        img, lab = render_road(cam, scene, pan=float(rng.uniform(-5, 5)))
        write_png(folder / "images" / f"s{seed}_{i}.png", img)
        write_png(folder / "labels" / f"s{seed}_{i}.png", lab)


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """6 synthetic CamVid-camera frames warped into the virtual camera at scale 0.02 (110x56),
    and the default (cpu recipe: resfpn, AdamW, augmentation) network at width 8 fitted on them."""
    root = tmp_path_factory.mktemp("vctrain")
    cam = PRESETS["camvid"].resized(0.1)  # 96x72
    _render_set(root / "src", cam, 6)
    fmt = get_label_format(FMT)
    store, _ = warp_dataset(list_dataset(root / "src/images", root / "src/labels", fmt), root / "store",
                            WarpSettings(cam, PRESETS["virtual"], 0.02, fmt, progress=False))
    cfg = TrainConfig(stores=[str(root / "store")], out=str(root / "model.pt"), base_width=8, epochs=20,
                      batch_size=2, val_fraction=0, progress=False, device="cpu", crop=1.0)  # (too small to window)
    summary = fit(cfg)
    return root, store, summary


def test_fit_learns_the_training_scenes(trained):
    root, store, summary = trained
    ck = load_checkpoint(root / "model.pt")
    model = model_from_checkpoint(ck)
    from vctrain.training import store_samples

    ds = RoadDataset(store_samples(store), store.store_size)
    m = evaluate(model, torch.utils.data.DataLoader(ds, batch_size=6), torch.device("cpu"))
    # trivial baseline: everything road -> IoU = road share of the labelled pixels
    labs = np.stack([ds.item(i)[1] for i in range(len(ds))])
    trivial = (labs == 1).sum() / (labs != 255).sum()
    assert m["iou"] > 0.85 and m["iou"] > trivial + 0.3
    log = [json.loads(l) for l in (root / "model.log.jsonl").read_text().splitlines()]
    assert [r["epoch"] for r in log] == list(range(1, 21)) and log[-1]["train_loss"] < log[0]["train_loss"]


def test_checkpoint_is_self_describing(trained):
    root, store, _ = trained
    ck = load_checkpoint(root / "model.pt")
    assert ck["model_args"] == {"arch": "resfpn", "base_width": 8, "in_channels": 3, "num_classes": 2}
    assert ck["data"]["mode"] == "virtual" and ck["data"]["input_size"] == [110, 56]
    assert ck["data"]["store_params"]["scale"] == 0.02
    assert ck["data"]["store_params"]["virtual"]["fx"] == 2262
    assert ck["config"]["recipe"] == "cpu" and ck["config"]["optimizer"] == "adamw" and ck["config"]["hflip"] is True
    assert ck["config"]["lr"] == RECIPES["cpu"]["lr"] and ck["epoch"] == 20
    model = model_from_checkpoint(ck)
    for k, v in model.state_dict().items():
        assert torch.equal(v, ck["model"][k])


def test_predict_other_camera_lands_on_road(trained, tmp_path):
    """Frames of another camera (Toronto, 102x58, other pose): warped in, inferred, back-projected;
    the mask must have the source size and match the rendered road."""
    root, _, _ = trained
    cam = PRESETS["toronto2020"].resized(0.1)
    _render_set(tmp_path / "new", cam, 2, seed=7)
    yaml = tmp_path / "cam.yaml"
    from vcprep.camera import camera_to_yaml

    yaml.write_text(camera_to_yaml(cam))
    r = runner.invoke(app, ["predict", str(root / "model.pt"), "--camera", str(yaml),
                            str(tmp_path / "new/images"), "--out", str(tmp_path / "pred"), "--quiet"])
    assert r.exit_code == 0, r.output
    assert len(r.stdout.split()) == 2
    ious = []
    for f in sorted((tmp_path / "new/images").iterdir()):
        mask = read_image(tmp_path / "pred" / f"{f.stem}_mask.png", label=True).array
        prob = read_image(tmp_path / "pred" / f"{f.stem}_prob.png", label=True).array
        lab = read_image(tmp_path / "new/labels" / f.name, label=True).array
        assert mask.shape == prob.shape == lab.shape == (58, 102)
        assert set(np.unique(mask)) <= {0, 255}
        assert ((prob >= 128) == (mask == 255)).all()
        ious.append(road_metrics([mask], [lab])["iou"])
    assert min(ious) > 0.6, ious

    # eval --json on the same predictions
    r = runner.invoke(app, ["eval", str(tmp_path / "pred"), "--labels", str(tmp_path / "new/labels"),
                            "--label-format", FMT, "--json", "--quiet"])
    assert r.exit_code == 0, r.output
    res = json.loads(r.stdout)
    assert {"iou", "precision", "recall", "f1", "maxf", "ap"} <= set(res)
    assert all(0.0 <= v <= 1.0 for v in res.values())
    assert res["iou"] > 0.6


def test_predict_bev_of_a_virtual_camera_model_equals_the_library_on_its_masks(trained, tmp_path):
    """predict --bev with a virtual-camera model (tests/test_predict_bev.py has the resize model's):
    each frame's BEV mask and JSON line are vcprep.bev's on its own perspective mask (--within none:
    the camera file's pose)."""
    from conftest import run_cli
    from test_predict_bev import BEV_ARGS, _check_frame

    from vcprep.bev import camera_view
    from vcprep.camera import camera_to_yaml

    root, _, _ = trained
    cam = PRESETS["camvid"].resized(0.1)
    _render_set(tmp_path / "new", cam, 2, seed=5)
    (tmp_path / "cam.yaml").write_text(camera_to_yaml(cam))
    r = run_cli("predict", root / "model.pt", tmp_path / "new/images", "--camera", tmp_path / "cam.yaml", "--within",
                "none", "--out", tmp_path / "pred", "-q", *BEV_ARGS, prog="vctrain")
    assert r.returncode == 0, r.stderr
    records = [json.loads(line) for line in r.stdout.splitlines()]
    assert [x["id"] for x in records] == ["s5_0", "s5_1"]
    for x in records:
        _check_frame(tmp_path / "pred", x["id"], x, camera_view(cam))


@pytest.mark.parametrize("beyond", ["hybrid", "rays", "extend"])
def test_predict_a_wider_steeper_camera_predicts_its_whole_frame(trained, tmp_path, beyond):
    """A camera wider and steeper than the virtual camera the model was trained in: a third of its
    frames' lower half lands outside the training rectangle, and none of it is scored 'not road'
    for that. With --beyond extend the kept store's virtual camera is the training's extended (same
    focal length and height) to hold them and the network predicts them; with rays the frames are
    warped into the training rectangle and those pixels take the value where the ray from the road
    VP leaves it; hybrid (the default) does both: the extended rectangle, rays beyond the training
    one. (How
    well a model does there is the benchmarks' question: benchmarks/archive/other_cameras/low_camera.py.)"""
    from vcprep.warp import backproject_array, backproject_rays
    from vcprep.camera import Camera, camera_to_yaml
    from vcprep.warp import virt_H_src
    from vcprep.store import Store
    from vcprep.camera import same_camera_other_canvas
    from vctrain.training import vp_in_store

    root, store, _ = trained
    # 110 x 94 deg, tilted 12 deg down: beyond the paper's virtual camera (101 x 64 deg) on every side
    cam = Camera("wide", (160, 120), 56.0, 56.0, 79.5, 59.5, 1.3, tilt=12.0)
    _render_set(tmp_path / "new", cam, 2, seed=5)
    (tmp_path / "cam.yaml").write_text(camera_to_yaml(cam))
    r = runner.invoke(app, ["predict", str(root / "model.pt"), "--camera", str(tmp_path / "cam.yaml"), "--within",
                            "none", str(tmp_path / "new/images"), "--out", str(tmp_path / "pred"), "--keep-store",
                            str(tmp_path / "kept"), "--quiet", *(["--beyond", beyond] if beyond != "hybrid" else [])])
    assert r.exit_code == 0, r.output
    kept = Store.open(tmp_path / "kept")
    assert same_camera_other_canvas(kept.params["virtual"], store.params["virtual"])
    if beyond in ("extend", "hybrid"):
        assert kept.store_size[0] > store.store_size[0] and kept.store_size[1] > store.store_size[1]
    else:
        assert kept.params["virtual"] == store.params["virtual"]
    # (in the training's rectangle a third of the lower half falls outside)
    ys, xs = np.mgrid[60:120, 0:160]
    p = virt_H_src(cam, PRESETS["virtual"].resized(0.02)) @ np.stack([xs.ravel(), ys.ravel(), np.ones(xs.size)])
    u, v = p[0] / p[2], p[1] / p[2]
    assert ((u < -0.5) | (u > store.store_size[0] - 0.5) | (v > store.store_size[1] - 0.5)).mean() > 0.3
    for rec in kept:
        w, h = rec["size"]
        full = np.ones(tuple(reversed(kept.store_size)), np.float32)
        cover = (backproject_array(full, rec, "prob") if beyond == "extend" else
                 backproject_rays(full, rec, vp_in_store(rec))) > 0.999
        assert cover[(h - 1) // 2 + 1:].all()
        assert read_image(tmp_path / "pred" / f"{rec['id']}_mask.png", label=True).array.shape == (h, w)


def test_predict_beyond_is_checked(trained, tmp_path):
    """--beyond: an unknown rule, and a model that has no rectangle to go beyond (the prior), are
    refused with one line naming the fix, before anything is written."""
    from conftest import assert_one_error_line, run_cli

    root, store, _ = trained
    image = next(iter(store))["source"]
    proc = run_cli("predict", root / "model.pt", "--camera", "camvid", image, "--out", tmp_path / "p", "--beyond",
                   "sideways", prog="vctrain")
    assert_one_error_line(proc, "unknown --beyond 'sideways'", "extend, rays, hybrid")
    assert not (tmp_path / "p").exists()


def test_predict_store_and_resize_baseline(trained, tmp_path):
    root, store, _ = trained
    r = runner.invoke(app, ["predict", str(root / "model.pt"), "--store", str(root / "store"),
                            "--out", str(tmp_path / "vs"), "--quiet"])
    assert r.exit_code == 0, r.output
    assert len(list((tmp_path / "vs").glob("*_mask.png"))) == 6
    # the paper's baseline: the same network on the original images simply resized
    r = runner.invoke(app, ["fit", str(root / "store"), "--baseline", "resize", "--size", "64x48", "--width", "8",
                            "--epochs", "2", "--batch-size", "3", "--val-fraction", "0.34",
                            "--out", str(tmp_path / "resize.pt"), "--quiet", "--json"])
    assert r.exit_code == 0, r.output
    summary = json.loads(r.stdout)
    assert summary["data"]["mode"] == "resize" and summary["best_val_iou"] is not None
    ck = load_checkpoint(tmp_path / "resize.pt")
    assert ck["data"]["input_size"] == [64, 48]
    img = sorted((root / "src/images").iterdir())[0]
    r = runner.invoke(app, ["predict", str(tmp_path / "resize.pt"), str(img), "--out", str(tmp_path / "rp"), "--quiet"])
    assert r.exit_code == 0, r.output
    assert read_image(tmp_path / "rp" / f"{img.stem}_mask.png", label=True).array.shape == (72, 96)
    # no --size: the store's pixel count (110x56 = 6160) at the frames' own 4:3 (96x72), not the store's 2:1
    r = runner.invoke(app, ["fit", str(root / "store"), "--baseline", "resize", "--width", "8", "--epochs", "1",
                            "--batch-size", "3", "--val-fraction", "0", "--out", str(tmp_path / "rs2.pt"), "--quiet"])
    assert r.exit_code == 0, r.output
    w, h = load_checkpoint(tmp_path / "rs2.pt")["data"]["input_size"]
    assert (w, h) == (91, 68) and abs(w / h - 96 / 72) < 0.01 and abs(w * h - 110 * 56) < 110


def test_predict_store_in_a_wider_canvas_of_the_models_virtual_camera(trained, tmp_path):
    """A store of the model's virtual camera with a larger rectangle (crossval's canvas: footprint)
    is predicted at the training's pixels per degree, whole; a store of another virtual camera
    (another focal length) is refused in one line."""
    from dataclasses import replace

    from vctrain.predict import Predictor

    root, store, _ = trained
    cam, v = PRESETS["camvid"].resized(0.1), PRESETS["virtual"]
    jobs = list_dataset(root / "src/images", root / "src/labels", get_label_format(FMT))
    wide, _ = warp_dataset(jobs, tmp_path / "wide", WarpSettings(
        cam, replace(v, size=(v.size[0] + 1000, v.size[1]), cx=v.cx + 500), 0.02, get_label_format(FMT),
        progress=False))
    assert wide.store_size[0] == store.store_size[0] + 20 and wide.store_size[1] == store.store_size[1]
    pred = Predictor(root / "model.pt", device="cpu")
    assert pred.working_size(tuple(wide.store_size)) == tuple(wide.store_size)
    r = runner.invoke(app, ["predict", str(root / "model.pt"), "--store", str(tmp_path / "wide"),
                            "--out", str(tmp_path / "wp"), "--quiet"])
    assert r.exit_code == 0, r.output
    masks = sorted((tmp_path / "wp").glob("*_mask.png"))
    assert len(masks) == 6 and all(read_image(m, label=True).array.shape == (72, 96) for m in masks)
    warp_dataset(jobs, tmp_path / "other", WarpSettings(cam, replace(v, fx=v.fx * 1.1, fy=v.fy * 1.1), 0.02,
                                                        get_label_format(FMT), progress=False))
    r = runner.invoke(app, ["predict", str(root / "model.pt"), "--store", str(tmp_path / "other"),
                            "--out", str(tmp_path / "op"), "--quiet"])
    assert r.exit_code != 0 and "another virtual camera than the model's training store" in str(r.exception)


def test_fit_on_crops_predicts_on_the_whole_image(trained, tmp_path):
    """--crop trains on windows (the checkpoint records both sizes) and validation and prediction
    run on the whole working image (fully convolutional), so masks keep the source size."""
    root, store, _ = trained
    r = runner.invoke(app, ["fit", str(root / "store"), "--crop", "0.6", "--width", "4", "--epochs", "1",
                            "--batch-size", "3", "--val-fraction", "0.34", "--out", str(tmp_path / "c.pt"),
                            "--quiet", "--json"])
    assert r.exit_code == 0, r.output
    ck = load_checkpoint(tmp_path / "c.pt")
    assert ck["data"]["input_size"] == [110, 56] and ck["data"]["crop_size"] == [66, 34]
    assert ck["config"]["crop"] == 0.6
    r = runner.invoke(app, ["predict", str(tmp_path / "c.pt"), "--store", str(root / "store"),
                            "--out", str(tmp_path / "cp"), "--quiet"])
    assert r.exit_code == 0, r.output
    rec = next(iter(store))
    mask = read_image(tmp_path / "cp" / f"{rec['id']}_mask.png", label=True).array
    assert mask.shape == (72, 96)  # the source camera's size
    r = runner.invoke(app, ["fit", str(root / "store"), "--crop", "200x20", "--out", str(tmp_path / "d.pt")])
    assert r.exit_code != 0 and "does not fit the working size 110x56" in str(r.exception)


def test_resume_continues_exactly(trained, tmp_path):
    root, _, _ = trained
    # constant lr: a 1-epoch run then resumed to 2 equals a 2-epoch run (poly would decay over 1 epoch)
    base = dict(stores=[str(root / "store")], base_width=4, batch_size=3, lr=0.05, val_fraction=0.2, progress=False,
                schedule="constant",
                hflip=True)
    fit(TrainConfig(out=str(tmp_path / "full.pt"), epochs=2, **base))
    fit(TrainConfig(out=str(tmp_path / "half.pt"), epochs=1, **base))
    fit(TrainConfig(out=str(tmp_path / "half.pt"), epochs=2, resume=str(tmp_path / "half.last.pt"), **base))
    a = load_checkpoint(tmp_path / "full.last.pt")
    b = load_checkpoint(tmp_path / "half.last.pt")
    assert b["epoch"] == 2 and len(b["history"]) == 2
    for k in a["model"]:
        assert torch.allclose(a["model"][k].float(), b["model"][k].float(), atol=1e-6), k


def _json_objects(text: str) -> list:
    """Every JSON object in ``text``: the ranks of a torchrun job share one stdout, so two ranks'
    lines can land on one line, one object right after the other."""
    dec, out, i = json.JSONDecoder(), [], text.find("{")
    while i >= 0:
        obj, end = dec.raw_decode(text, i)
        out.append(obj)
        i = text.find("{", end)
    return out


def test_two_process_training_keeps_replicas_identical(trained, tmp_path):
    root, _, _ = trained
    torchrun = Path(sys.executable).with_name("torchrun")
    if not torchrun.exists():
        pytest.skip("torchrun not installed beside this python")
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    # vctrain fit, then the names of the threads still running when the command has returned: a
    # process group kept alive leaves gloo's threads, which can abort the exit (SIGABRT)
    script = tmp_path / "fit_then_threads.py"
    script.write_text("import json, os, sys\nfrom vctrain.cli import app\ntry:\n    app(sys.argv[1:])\n"
                      "except SystemExit as e:\n    code = e.code\n"
                      "tasks = os.listdir('/proc/self/task') if os.path.isdir('/proc/self/task') else []\n"
                      "names = [open(f'/proc/self/task/{t}/comm').read().strip() for t in tasks]\n"
                      "print(json.dumps({'threads': names}))\nsys.exit(code)\n")
    r = subprocess.run([str(torchrun), "--standalone", "--nproc-per-node", "2", str(script), "fit",
                        str(root / "store"), "--width", "4", "--epochs", "1", "--batch-size", "4",
                        "--val-fraction", "0", "--device", "cpu", "--out", str(tmp_path / "ddp.pt"), "--quiet", "--json"],
                       capture_output=True, text=True, env=env, timeout=120)
    # a failing rank's own message comes first; torchrun's summary of it last
    assert r.returncode == 0, r.stderr[:1500] + "\n...\n" + r.stderr[-800:]
    rows = _json_objects(r.stdout)
    summaries = [row for row in rows if "world_size" in row]
    assert len(summaries) == 2 and all(row["world_size"] == 2 and row["replicas_identical"] for row in summaries)
    threads = [row["threads"] for row in rows if "threads" in row]
    assert len(threads) == 2 and not any("gloo" in name for names in threads for name in names), threads
    assert load_checkpoint(tmp_path / "ddp.pt")["step"] == 2  # 6 items, global batch 4


# -- CLI -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("cmd", ["fit", "predict", "eval", "version"])
def test_every_command_has_an_example(cmd):
    r = runner.invoke(app, [cmd, "--help"])
    assert r.exit_code == 0 and "Example:" in r.stdout


def test_predict_help_shows_the_shipped_model_and_when_the_overlay_has_a_horizon():
    text = " ".join(runner.invoke(app, ["predict", "--help"]).stdout.split())
    example = text.split("Example:", 1)[1]
    assert "vctrain predict models/road-all/road.pt " in example
    overlay = text.split("Options:", 1)[1].split("--overlay", 1)[1].split(" --mask-video", 1)[0]
    assert "horizon" in overlay and "only with --camera" in overlay, overlay


def test_fit_help_names_the_recipes():
    text = " ".join(runner.invoke(app, ["fit", "--help"]).stdout.split())
    assert "resfpn" in text and "'cpu'" in text and "'paper'" in text


def test_fit_has_one_option_per_train_config_field():
    """Every TrainConfig field is set by exactly one fit option (named as the field, or as
    FIT_OPTION_FIELD says), except the fields fit leaves to the library; and the options given
    reach the config they name."""
    import typer.main
    from dataclasses import fields

    from vctrain.cli import FIT_NO_OPTION, FIT_NOT_CONFIG, FIT_OPTION_FIELD, _fit_config

    cmd = typer.main.get_command(app).commands["fit"]
    options = [p.name for p in cmd.params if p.name not in FIT_NOT_CONFIG]
    set_fields = [FIT_OPTION_FIELD.get(n, n) for n in options]
    assert sorted(set_fields) == sorted(f.name for f in fields(TrainConfig) if f.name not in FIT_NO_OPTION)
    args = ["s1", "s2", "-o", "runs/m.pt", "-m", "segnet-narrow", "--width", "4", "--val-store", "v", "--size",
            "64x48", "--crop", "0.5x1", "--seed", "3", "--no-hflip", "--quiet", "--log", "l.jsonl", "--epochs", "2"]
    cfg = _fit_config(cmd.make_context("fit", args).params)
    assert (cfg.stores, cfg.out, cfg.arch, cfg.base_width, cfg.val_stores) == (["s1", "s2"], "runs/m.pt",
                                                                               "segnet-narrow", 4, ["v"])
    assert (cfg.size, cfg.crop, cfg.seed, cfg.hflip, cfg.progress, cfg.log, cfg.epochs) == ((64, 48), (0.5, 1.0), 3,
                                                                                            False, False, "l.jsonl", 2)
    default = _fit_config(cmd.make_context("fit", ["s", "-o", "m.pt"]).params)
    assert default == TrainConfig(stores=["s"], out="m.pt")


@pytest.mark.parametrize("cmd, option", [("fit", "--label-format"), ("eval", "--label-format")])
def test_label_format_help_names_every_label_format(cmd, option):
    from vcprep.labels import LABEL_FORMATS

    text = " ".join(runner.invoke(app, [cmd, "--help"]).stdout.split()).replace("- ", "-")
    assert all(name in text for name in LABEL_FORMATS) and "idd" in text


def _cli(*args, process: bool = True):
    if not process:  # the console script's main() in this process (conftest.run_cli)
        from conftest import run_cli

        return run_cli(*args, prog="vctrain")
    return subprocess.run([sys.executable, "-m", "vctrain.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=60)


def test_bad_inputs_give_one_error_line(tmp_path):
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"not a checkpoint")
    foreign = tmp_path / "foreign.pt"
    torch.save({"conv.weight": torch.zeros(2, 2)}, foreign)  # another architecture's state dict
    cases = [
        ("predict", junk, "--store", tmp_path, "--out", tmp_path / "o"),
        ("predict", foreign, "--store", tmp_path, "--out", tmp_path / "o"),
        ("predict", tmp_path / "missing.pt", "--store", tmp_path, "--out", tmp_path / "o"),
        ("fit", tmp_path / "no_store", "--out", tmp_path / "m.pt"),
        ("eval", tmp_path / "nothing", "--labels", tmp_path, "--label-format", "camvid"),
    ]
    for k, args in enumerate(cases):
        # the checkpoints torch.load reads in a new interpreter (what prints there prints); the rest,
        # refused before any model is built, in this one (a new interpreter importing torch: ~2 s)
        r = _cli(*args, process=k < 2)
        assert r.returncode != 0, args
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("Error:"), (args, r.stderr)
        assert "Traceback" not in r.stderr



def test_a_virtual_camera_model_without_a_camera_names_estimate(trained, tmp_path):
    """A user with an uncalibrated camera is told the answer: the one error line's fix names
    ``--camera`` 'estimate'."""
    import cv2

    from vcprep.synthetic import render_road

    from conftest import run_cli

    root, _, _ = trained
    (tmp_path / "imgs").mkdir()
    cv2.imwrite(str(tmp_path / "imgs" / "f0.png"), render_road(PRESETS["camvid"].resized(0.25))[0])
    r = run_cli("predict", root / "model.pt", tmp_path / "imgs", "--out", tmp_path / "pred", prog="vctrain")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1 and len(lines) == 1 and lines[0].startswith("Error:"), r.stderr
    assert "needs the camera" in lines[0] and "--camera" in lines[0] and "'estimate'" in lines[0]


def test_eval_scores_the_frames_of_one_model_and_names_what_it_leaves_out(trained, tmp_path):
    """Model A predicts six frames into a folder, model B (other weights) one of them into the same
    folder: eval scores B's one frame and says that five masks of another model's run are left out;
    B's second run into the folder adds its frame (two scored, nothing said)."""
    import shutil

    from conftest import run_cli
    from vcprep.camera import camera_to_yaml
    from vctrain.training import load_checkpoint, save_checkpoint

    root, _, _ = trained
    cam_file = tmp_path / "cam.yaml"
    cam_file.write_text(camera_to_yaml(PRESETS["camvid"].resized(0.1)))
    ck = load_checkpoint(root / "model.pt")
    ck["model"] = {k: v + 0.01 if v.is_floating_point() else v for k, v in ck["model"].items()}
    save_checkpoint(tmp_path / "b.pt", ck)
    frames = sorted((root / "src" / "images").glob("*.png"))
    for name, files in (("one", frames[:1]), ("two", frames[1:2])):
        (tmp_path / name).mkdir()
        for f in files:
            shutil.copy(f, tmp_path / name / f.name)
    out, labels = tmp_path / "preds", root / "src" / "labels"

    def predict(model, images):
        r = run_cli("predict", model, images, "--camera", cam_file, "--out", out, "-q", prog="vctrain")
        assert r.returncode == 0, r.stderr

    def scored():
        r = run_cli("eval", out, "--labels", labels, "--label-format", FMT, "-q", prog="vctrain")
        assert r.returncode == 0, r.stderr
        return r.stdout.splitlines()[0], r.stderr.strip()

    predict(root / "model.pt", root / "src" / "images")
    assert scored() == (f"# {out}: 6 frames scored against {labels} ({FMT})", "")
    predict(tmp_path / "b.pt", tmp_path / "one")
    head, said = scored()
    assert head == f"# {out}: 1 frame scored against {labels} ({FMT})"
    assert "5 of its 6 masks were not written by the model of its last predict run" in said and "b.pt" in said
    predict(tmp_path / "b.pt", tmp_path / "two")
    head, said = scored()
    assert head.startswith(f"# {out}: 2 frames scored") and "4 of its 6 masks" in said
    record = json.loads((out / "predict.json").read_text())
    assert record["frames"] == [frames[0].stem, frames[1].stem] and record["model"] == str(tmp_path / "b.pt")


def test_a_tree_whose_frames_repeat_names_is_predicted_as_a_tree_and_scored(trained, tmp_path):
    """IDD's layout, ``<drive>/<frame>.png`` with frame names repeated from drive to drive: predict
    writes each frame's outputs in its drive's folder of --out (nothing overwritten: a drive's masks
    equal those of that drive predicted alone), and eval scores every frame against the label of the
    same name in the same folder (the IoU of the masks and labels read back by hand)."""
    import shutil

    from conftest import run_cli
    from vcprep.camera import camera_to_yaml
    from vcprep.labels import decode_label

    def _png(path):
        return read_image(path, label=True).array

    root, _, _ = trained
    cam_file = tmp_path / "cam.yaml"
    cam_file.write_text(camera_to_yaml(PRESETS["camvid"].resized(0.1)))
    frames = sorted((root / "src" / "images").glob("*.png"))
    labels = sorted((root / "src" / "labels").glob("*.png"))
    tree = {"d1": (0, 1, 2), "d2": (3, 4)}  # d2's frames take d1's first names
    for drive, picks in tree.items():
        for k, i in enumerate(picks):
            for kind, files in (("images", frames), ("labels", labels)):
                (tmp_path / kind / drive).mkdir(parents=True, exist_ok=True)
                shutil.copy(files[i], tmp_path / kind / drive / f"f{k}.png")
    common = ("--camera", cam_file, "--within", "none", "-q")
    r = run_cli("predict", root / "model.pt", tmp_path / "images", "--out", tmp_path / "out", *common, prog="vctrain")
    assert r.returncode == 0, r.stderr
    alone = run_cli("predict", root / "model.pt", tmp_path / "images" / "d2", "--out", tmp_path / "d2", *common,
                    prog="vctrain")
    assert alone.returncode == 0, alone.stderr
    for k in range(2):
        for kind in ("mask", "prob"):
            assert np.array_equal(_png(tmp_path / "out" / "d2" / f"f{k}_{kind}.png"),
                                  _png(tmp_path / "d2" / f"f{k}_{kind}.png"))
    assert not (tmp_path / "out" / "f0_mask.png").exists()
    tp = fp = fn = 0
    fmt = get_label_format(FMT)
    for drive, picks in tree.items():
        for k in range(len(picks)):
            pred = _png(tmp_path / "out" / drive / f"f{k}_mask.png") > 0
            lab = decode_label(_png(tmp_path / "labels" / drive / f"f{k}.png"), fmt)
            tp += int((pred & (lab == 1)).sum())
            fp += int((pred & (lab == 0)).sum())
            fn += int((~pred & (lab == 1)).sum())
    ev = run_cli("eval", tmp_path / "out", "--labels", tmp_path / "labels", "-f", FMT, "--json", "-q", prog="vctrain")
    assert ev.returncode == 0, ev.stderr
    assert json.loads(ev.stdout)["iou"] == pytest.approx(tp / (tp + fp + fn), abs=1e-9)
    head = run_cli("eval", tmp_path / "out", "--labels", tmp_path / "labels", "-f", FMT, "-q", prog="vctrain")
    assert head.stdout.startswith(f"# {tmp_path / 'out'}: 5 frames scored")

def test_predict_with_given_vps_and_overlay(trained, tmp_path):
    """A re-mounted camera (pan 8, tilt -4): with its VP given, predict warps with that pose (the
    kept store's record says so and its VP maps to the virtual principal point) and draws an overlay."""
    import cv2

    from vcprep.camera import camera_to_yaml
    from vcprep.warp import apply_homography, vp_from_pose
    from vcprep.store import Store
    from vcprep.synthetic import render_road

    root, _, _ = trained
    cam = PRESETS["toronto2020"].resized(0.1)
    (tmp_path / "imgs").mkdir()
    img, lab = render_road(cam, pan=8.0, tilt=-4.0)
    cv2.imwrite(str(tmp_path / "imgs" / "f0.png"), img)
    u, v = vp_from_pose(cam, 8.0, -4.0)
    (tmp_path / "vps.csv").write_text(f"id,u,v\nf0,{u},{v}\n")
    (tmp_path / "cam.yaml").write_text(camera_to_yaml(cam))
    r = runner.invoke(app, ["predict", str(root / "model.pt"), "--camera", str(tmp_path / "cam.yaml"),
                            str(tmp_path / "imgs"), "--within", str(tmp_path / "vps.csv"), "--overlay",
                            "--keep-store", str(tmp_path / "kept"), "--out", str(tmp_path / "pred"), "--quiet"])
    assert r.exit_code == 0, r.output
    st = Store.open(tmp_path / "kept")
    rec = st.get("f0")
    assert rec["vp_status"] == "given"
    assert (rec["pan_deg"], rec["tilt_deg"]) == pytest.approx((8.0, -4.0), abs=1e-9)
    H = np.array(rec["H"]).reshape(3, 3)
    assert apply_homography(H, [rec["vp"]])[0] == pytest.approx([st.virtual.cx, st.virtual.cy], abs=1e-6)
    mask = read_image(tmp_path / "pred" / "f0_mask.png", label=True).array
    assert mask.shape == lab.shape
    overlay = read_image(tmp_path / "pred" / "f0_overlay.png").array
    assert overlay.shape == img.shape
    assert np.array_equal(overlay[mask == 0], img[mask == 0])  # untouched where no road is predicted
    assert (overlay[mask > 0] != img[mask > 0]).any(axis=-1).mean() > 0.9  # tinted where road is


def test_eval_table_says_what_it_scores_and_what_iou_and_maxf_are(tmp_path):
    """The human-readable table names the prediction folder and the number of frames it scores and
    has a one-line note on IoU (the mask) against MaxF (the best threshold of P); --json is the
    metrics object alone, as before."""
    from conftest import run_cli

    kitti = Path(__file__).resolve().parent.parent / "examples" / "kitti"
    label = read_image(kitti / "gt_image_2" / "um_road_000000.png").array
    road = (label[..., 0] > 0) & (label[..., 2] > 0) if label.ndim == 3 else label > 0
    prob = np.where(road, 200, 140).astype(np.uint8)  # road ranked first, but P >= 0.5 everywhere
    pred = tmp_path / "preds"
    pred.mkdir()
    write_png(pred / "um_000000_prob.png", prob, kind="mask")
    write_png(pred / "um_000000_mask.png", np.where(prob >= 128, 255, 0).astype(np.uint8), kind="mask")
    args = ("eval", pred, "--labels", kitti / "gt_image_2", "--label-format", "kitti", "-q")
    text = run_cli(*args, prog="vctrain")
    assert text.returncode == 0, text.stderr
    lines = text.stdout.splitlines()
    assert lines[0] == f"# {pred}: 1 frame scored against {kitti / 'gt_image_2'} (kitti)", lines[0]
    table = {ln.split()[0]: float(ln.split()[1]) for ln in lines if not ln.startswith("#")}
    assert table["iou"] < 0.6 and table["maxf"] > 0.99  # the mask is poor, the ranking perfect
    notes = [ln for ln in lines[1:] if ln.startswith("#")]
    assert len(notes) == 1 and "maxf" in notes[0] and "P >= 0.5" in notes[0] and "thresholds" in notes[0], notes
    js = run_cli(*args, "--json", prog="vctrain")
    assert js.returncode == 0 and len(js.stdout.splitlines()) == 1
    assert json.loads(js.stdout) == pytest.approx(table, abs=1e-4)
