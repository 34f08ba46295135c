"""A camera that sees its own vehicle: ``ego_rows`` in the camera YAML.

The oracle is the hand crop the README used to prescribe: warping full frames with
``ego_rows: N`` must give exactly the store that warping the frames cropped by N bottom rows gives
with the camera at the cropped size (same K); back-projection must return the full frame, its
rows above the vehicle equal to the hand-cropped back-projection."""
from __future__ import annotations

import json
import shutil
from dataclasses import replace

import cv2
import numpy as np
import pytest

from vcprep.warp import backproject_array
from vcprep.store import store_params
from vcprep.camera import PRESETS, Camera, camera_to_yaml, read_camera_yaml
from vcprep.errors import InputError
from vcprep.warp import vp_from_pose
from vcprep.synthetic import RoadScene, render_road

from conftest import PAPER_STORE, run_here, assert_one_error_line, run_cli


def _camera_ego(*args):
    """``vcprep camera ego ARGS``, the command's entry point run in this process (conftest.run_here:
    argv, stdout and stderr apart, the exit status): it reads labels or frames and prints, no pool or
    signal, and a new interpreter cost ~0.4 s a call."""
    return run_here("camera", "ego", *args)


EGO = 36  # CamVid 0001TP: the bonnet fills the bottom 36 rows of the 480x360 frames
BONNET_BGR = (255, 0, 255)  # magenta: no colour of the synthetic scene comes near it
GOOD = """name: mycam
image_size: [960, 720]
fx: 862
fy: 1141
cx: 485
cy: 365
height: 1.21
"""


def _is_bonnet(img: np.ndarray) -> np.ndarray:
    b, g, r = (img[..., c].astype(int) for c in range(3))
    return (b > 180) & (r > 180) & (g < 60)


@pytest.fixture(scope="module")
def frames(tmp_path_factory, camvid_half):
    """Three 480x360 road frames whose bottom 36 rows show a magenta bonnet labelled ROAD (3) (the
    worst case: only the crop keeps it out of the virtual road), their hand-cropped 480x324
    copies, camera files for both, and a VP table that pitches each frame differently."""
    root = tmp_path_factory.mktemp("ego")
    full_i, full_l, crop_i, crop_l = (root / d for d in ("full/images", "full/labels", "crop/images", "crop/labels"))
    for d in (full_i, full_l, crop_i, crop_l):
        d.mkdir(parents=True)
    vps = []
    for i, (pan, tilt) in enumerate([(0.0, 0.0), (4.0, -3.0), (-3.0, 4.0)]):
        img, lab = render_road(camvid_half, RoadScene(offset=0.3 * i, texture_seed=i), pan=pan, tilt=tilt,
                               supersample=1)
        ids = np.where(lab == 1, 3, 0).astype(np.uint8)
        img[-EGO:] = BONNET_BGR
        ids[-EGO:] = 3
        name = f"seq_{i:04d}.png"
        cv2.imwrite(str(full_i / name), img)
        cv2.imwrite(str(full_l / name), ids)
        cv2.imwrite(str(crop_i / name), img[:-EGO])
        cv2.imwrite(str(crop_l / name), ids[:-EGO])
        u, v = vp_from_pose(camvid_half, pan, tilt)  # off the average pose: within-camera correction
        vps.append(f"seq_{i:04d},{u:.6f},{v:.6f}")
    (root / "vps.csv").write_text("id,u,v\n" + "\n".join(vps) + "\n")
    ego = replace(camvid_half, name="rig", ego_rows=EGO)
    (root / "ego.yaml").write_text(camera_to_yaml(ego))
    (root / "noego.yaml").write_text(camera_to_yaml(replace(ego, ego_rows=0)))
    (root / "crop.yaml").write_text(camera_to_yaml(ego.without_ego()))
    return root


def _warp(root, which, camera, out, *extra):
    proc = run_cli("warp", "--camera", root / camera, "--images", root / which / "images", "--labels",
                   root / which / "labels", "--label-format", "camvid", *PAPER_STORE, "--scale", "0.1", "--out", out,
                   "--within", root / "vps.csv", "--jobs", "1", *extra)
    assert proc.returncode == 0, proc.stderr
    return proc


def _records(store):
    return [json.loads(line) for line in (store / "manifest.jsonl").read_text().splitlines()]


def _png(path):
    return cv2.imread(str(path), cv2.IMREAD_UNCHANGED)


@pytest.fixture(scope="module")
def stores(frames, tmp_path_factory):
    out = tmp_path_factory.mktemp("ego_stores")
    _warp(frames, "full", "ego.yaml", out / "ego")
    _warp(frames, "crop", "crop.yaml", out / "crop")
    _warp(frames, "full", "noego.yaml", out / "noego")
    return out


# -- the camera model -------------------------------------------------------------------------------

def test_yaml_ego_rows_round_trip(tmp_path):
    p = tmp_path / "cam.yaml"
    p.write_text(GOOD + "ego_rows: 72\n")
    cam = read_camera_yaml(p)
    assert cam.ego_rows == 72 and cam.visible_size == (960, 648)
    assert cam.to_dict()["ego_rows"] == 72
    p2 = tmp_path / "again.yaml"
    p2.write_text(camera_to_yaml(cam))
    assert "ego_rows: 72" in p2.read_text() and read_camera_yaml(p2) == cam
    # no ego_rows: the camera, its dict and its YAML are what they were before the key existed
    p.write_text(GOOD)
    plain = read_camera_yaml(p)
    assert plain.ego_rows == 0 and "ego_rows" not in plain.to_dict() and "ego_rows" not in camera_to_yaml(plain)
    assert all(c.ego_rows == 0 for c in PRESETS.values())
    # the camera without its ego rows: an exact bottom crop (same K, 72 rows shorter)
    crop = cam.without_ego()
    assert crop.size == (960, 648) and crop.ego_rows == 0 and np.array_equal(crop.K, cam.K)


@pytest.mark.parametrize("value, needle", [
    ("-1", "'ego_rows' must be a whole number"),
    ("3.5", "'ego_rows' must be a whole number"),
    ("true", "'ego_rows' must be a whole number"),
    ("abc", "'ego_rows' must be a whole number"),
    ("720", "'ego_rows' is 720 but the image has only 720 rows"),
    ("1000", "'ego_rows' is 1000"),
])
def test_yaml_ego_rows_errors_name_file_and_key(tmp_path, value, needle):
    p = tmp_path / "bad.yaml"
    p.write_text(GOOD + f"ego_rows: {value}\n")
    with pytest.raises(InputError) as e:
        read_camera_yaml(p)
    assert needle in str(e.value) and str(p) in str(e.value)


def test_ego_rows_scale_with_the_image_size_rounded_up():
    cam = Camera("rig", (960, 720), 862, 1141, 485, 365, 1.21, ego_rows=72)
    assert cam.for_image_size((480, 360)).ego_rows == 36
    assert cam.for_image_size((1920, 1440)).ego_rows == 144
    # 71 full-size rows are 35.5 half-size rows: the half row is excluded too
    assert Camera("rig", (960, 720), 862, 1141, 485, 365, 1.21, ego_rows=71).for_image_size((480, 360)).ego_rows == 36
    assert Camera("rig", (960, 720), 862, 1141, 485, 365, 1.21, ego_rows=1).for_image_size((480, 360)).ego_rows == 1
    assert cam.resized(0.1).size == (96, 72) and cam.resized(0.1).ego_rows == 8  # 7.2 -> 8
    # K follows the pixel-centre rule as for any camera; no ego rows stay none at any size
    assert cam.for_image_size((480, 360)).fy == 570.5
    assert PRESETS["camvid"].for_image_size((480, 360)).ego_rows == 0
    assert PRESETS["virtual"].resized(0.125).ego_rows == 0


def test_a_virtual_camera_with_ego_rows_is_refused(tmp_path, frames):
    v = Camera("v", (5500, 2800), 2262, 2262, 2749.5, 1399.5, 1.38, ego_rows=10)
    with pytest.raises(InputError, match="ego_rows"):
        store_params(v, 0.1)
    (tmp_path / "v.yaml").write_text(camera_to_yaml(v))
    proc = run_cli("warp", "--camera", frames / "ego.yaml", "--images", frames / "full/images", "--virtual",
                   tmp_path / "v.yaml", "--out", tmp_path / "s")
    assert_one_error_line(proc, "ego_rows")
    assert not (tmp_path / "s" / "manifest.jsonl").exists()


# -- warp: ego_rows == the hand crop ----------------------------------------------------------------

def test_warp_with_ego_rows_equals_the_hand_cropped_warp(stores):
    ego, crop = _records(stores / "ego"), _records(stores / "crop")
    assert [r["id"] for r in ego] == [r["id"] for r in crop] == ["seq_0000", "seq_0001", "seq_0002"]
    for a, b in zip(ego, crop):
        assert a["H"] == b["H"] and a["vp"] == b["vp"] and a["pan_deg"] == b["pan_deg"]
        assert a["size"] == [480, 360] and a["ego_rows"] == EGO  # the record keeps the full frame
        assert b["size"] == [480, 324] and "ego_rows" not in b
        assert a["camera_params"]["ego_rows"] == EGO
        assert a["valid"] == b["valid"]  # same geometry: the same shared valid mask
        assert a["completion_centre"] == b["completion_centre"]
        for k in ("image", "label", "valid"):
            x, y = _png(stores / "ego" / a[k]), _png(stores / "crop" / b[k])
            assert x.shape == y.shape and np.array_equal(x, y), (a["id"], k)


def test_no_bonnet_pixel_reaches_the_virtual_image(stores):
    """... while without ego_rows the bonnet lands in the store (the check can fail), with its
    'road' label."""
    for a, n in zip(_records(stores / "ego"), _records(stores / "noego")):
        assert not _is_bonnet(_png(stores / "ego" / a["image"])).any()
        img_n = _png(stores / "noego" / n["image"])
        bonnet = _is_bonnet(img_n)
        assert bonnet.sum() > 500
        assert (_png(stores / "noego" / n["label"])[bonnet] == 1).mean() > 0.9  # its 'road' label went along
        # with ego_rows those store pixels are completed from the scene above the bonnet (asphalt etc.)
        assert _png(stores / "ego" / a["valid"])[bonnet].sum() == 0
        assert n["H"] == a["H"]


def test_warped_labels_are_ignore_where_the_ego_rows_would_land(frames, tmp_path):
    """Bare warp (no completion): the store pixels the bonnet would cover are uncovered, label 255."""
    _warp(frames, "full", "ego.yaml", tmp_path / "ego", "--complete", "none")
    _warp(frames, "full", "noego.yaml", tmp_path / "noego", "--complete", "none")
    for a, n in zip(_records(tmp_path / "ego"), _records(tmp_path / "noego")):
        bonnet = _is_bonnet(_png(tmp_path / "noego" / n["image"]))
        assert bonnet.sum() > 500
        assert (_png(tmp_path / "ego" / a["label"])[bonnet] == 255).all()
        assert (_png(tmp_path / "ego" / a["valid"])[bonnet] == 0).all()
        assert not _png(tmp_path / "ego" / a["image"])[bonnet].any()


def test_complete_of_an_ego_store_equals_warp_with_completion(frames, stores, tmp_path):
    out = tmp_path / "later"
    _warp(frames, "full", "ego.yaml", out, "--complete", "none")
    proc = run_cli("complete", out, "--jobs", "1")
    assert proc.returncode == 0, proc.stderr
    for a, b in zip(_records(out), _records(stores / "ego")):
        assert a["key"] == b["key"] and a["valid"] == b["valid"] and a["ego_rows"] == EGO
        for k in ("image", "label", "valid"):
            assert np.array_equal(_png(out / a[k]), _png(stores / "ego" / b[k])), k


def test_ego_rows_0_keeps_existing_stores_up_to_date_and_a_change_rebuilds(frames, tmp_path):
    out = tmp_path / "s"
    plain = frames / "plain.yaml"
    plain.write_text((frames / "noego.yaml").read_text())
    assert "ego_rows" not in plain.read_text()
    _warp(frames, "full", "plain.yaml", out)
    explicit = tmp_path / "zero.yaml"
    explicit.write_text(plain.read_text() + "ego_rows: 0\n")
    proc = run_cli("warp", "--camera", explicit, "--images", frames / "full/images", "--labels",
                   frames / "full/labels", "--label-format", "camvid", "--scale", "0.1", "--out", out,
                   "--within", frames / "vps.csv", "--jobs", "1")
    assert proc.returncode == 0 and "0 built, 3 up to date" in proc.stderr, proc.stderr
    proc = _warp(frames, "full", "ego.yaml", out)
    assert "3 built, 0 up to date" in proc.stderr
    assert all(r["ego_rows"] == EGO for r in _records(out))


# -- back-projection: the full frame, the ego rows predicted from the completed store ----------------

def test_backproject_gives_the_full_frame_and_extends_the_scene_over_the_ego_rows(stores, tmp_path):
    """The rows above the vehicle equal the hand-cropped back-projection; the ego rows are
    back-projected through the same H as every pixel (the road beside a bonnet is predicted, not
    declared 'not road'), i.e. exactly what the record without ``ego_rows`` gives."""
    recs = {r["id"]: r for r in _records(stores / "ego")}
    masks = tmp_path / "masks"
    masks.mkdir()
    w, h = recs["seq_0000"]["store_size"]
    rng = np.random.default_rng(0)
    store_masks = {i: (rng.random((h, w)) > 0.5).astype(np.uint8) * 255 for i in recs}
    for i, m in store_masks.items():
        cv2.imwrite(str(masks / f"{i}.png"), m)
    for store, out in ((stores / "ego", tmp_path / "back_ego"), (stores / "crop", tmp_path / "back_crop")):
        proc = run_cli("backproject", store, masks, "--out", out, "--kind", "mask", "--quiet")
        assert proc.returncode == 0, proc.stderr
    for i in recs:
        full, cropped = _png(tmp_path / "back_ego" / f"{i}.png"), _png(tmp_path / "back_crop" / f"{i}.png")
        assert full.shape == (360, 480) and cropped.shape == (324, 480)
        assert np.array_equal(full[:-EGO], cropped)
        plain = {k: v for k, v in recs[i].items() if k != "ego_rows"}
        assert np.array_equal(full, backproject_array(store_masks[i], plain, "mask"))
        assert full[-EGO:].any() and not full[-EGO:].all()  # the ego rows carry the store's prediction


def test_a_record_without_ego_rows_backprojects_as_before(stores):
    rec = _records(stores / "noego")[0]
    assert "ego_rows" not in rec
    w, h = rec["store_size"]
    m = backproject_array(np.ones((h, w), np.uint8), rec, "mask")
    assert m.shape == (360, 480) and m[-EGO:].all()  # the whole frame lands inside the store


# -- vctrain predict on raw images ------------------------------------------------------------------

@pytest.fixture(scope="module")
def tiny_model(tmp_path_factory):
    """A tiny virtual-camera checkpoint (2 epochs, width 4) on synthetic 96x72 CamVid-camera frames."""
    from vcprep.store import WarpSettings, warp_dataset
    from vcprep.dataset import list_dataset
    from vcprep.labels import get_label_format
    from vctrain.training import TrainConfig, fit

    root = tmp_path_factory.mktemp("ego_model")
    cam = PRESETS["camvid"].resized(0.1)  # 96x72
    (root / "images").mkdir()
    (root / "labels").mkdir()
    for i in range(4):
        img, lab = render_road(cam, RoadScene(offset=0.5 * i - 1, texture_seed=20 + i), pan=2.0 * i - 3)
        cv2.imwrite(str(root / "images" / f"t{i}.png"), img)
        cv2.imwrite(str(root / "labels" / f"t{i}.png"), lab)
    fmt = get_label_format("values:road=1")
    warp_dataset(list_dataset(root / "images", root / "labels", fmt), root / "store",
                 WarpSettings(cam, PRESETS["virtual"], 0.02, fmt, progress=False))
    fit(TrainConfig(stores=[str(root / "store")], out=str(root / "model.pt"), base_width=4, epochs=2, batch_size=2,
                    val_fraction=0, progress=False, device="cpu"))
    return root / "model.pt"


def test_predict_with_ego_rows_gives_full_frames(tiny_model, tmp_path):
    """vctrain predict on raw frames of a camera with ego_rows: full-size outputs whose rows above
    the vehicle are exactly the hand-cropped frames' prediction, whatever the bonnet shows."""
    cam = replace(PRESETS["camvid"].resized(0.1), name="rig", ego_rows=8)  # 96x72
    full, crop, other = tmp_path / "full", tmp_path / "crop", tmp_path / "other"
    for d in (full, crop, other):
        d.mkdir()
    for i in range(2):
        img, _ = render_road(cam, RoadScene(offset=0.4 * i, texture_seed=40 + i))
        img[-8:] = BONNET_BGR
        cv2.imwrite(str(full / f"p{i}.png"), img)
        cv2.imwrite(str(crop / f"p{i}.png"), img[:-8])
        img[-8:] = (0, 255, 0)  # another bonnet: must change nothing
        cv2.imwrite(str(other / f"p{i}.png"), img)
    (tmp_path / "ego.yaml").write_text(camera_to_yaml(cam))
    (tmp_path / "crop.yaml").write_text(camera_to_yaml(cam.without_ego()))
    for cam_file, images, out in (("ego.yaml", full, "pred_ego"), ("crop.yaml", crop, "pred_crop"),
                                  ("ego.yaml", other, "pred_other")):
        proc = run_cli("predict", tiny_model, "--camera", tmp_path / cam_file, images, "--out", tmp_path / out,
                       "--quiet", prog="vctrain")
        assert proc.returncode == 0, proc.stderr
    for i in range(2):
        prob, mask = _png(tmp_path / "pred_ego" / f"p{i}_prob.png"), _png(tmp_path / "pred_ego" / f"p{i}_mask.png")
        assert prob.shape == mask.shape == (72, 96)
        assert prob[:-8].any()
        # the rows above: exactly what the hand-cropped frames give
        assert np.array_equal(prob[:-8], _png(tmp_path / "pred_crop" / f"p{i}_prob.png"))
        assert np.array_equal(mask[:-8], _png(tmp_path / "pred_crop" / f"p{i}_mask.png"))
        assert np.array_equal(prob, _png(tmp_path / "pred_other" / f"p{i}_prob.png"))


def test_frame_camera_folders_take_ego_rows_from_their_yaml(frames, stores, tmp_path):
    """Per-frame calibration folders (one <stem>.yaml per frame) need nothing new."""
    calib = tmp_path / "calib"
    calib.mkdir()
    for i in range(3):
        shutil.copy(frames / "ego.yaml", calib / f"seq_{i:04d}.yaml")
    proc = run_cli("warp", "--camera", calib, "--images", frames / "full/images", "--scale", "0.1",
                   "--out", tmp_path / "s", "--jobs", "1", "--complete", "none")
    assert proc.returncode == 0, proc.stderr
    for r in _records(tmp_path / "s"):
        assert r["ego_rows"] == EGO and r["size"] == [480, 360]
        assert not _is_bonnet(_png(tmp_path / "s" / r["image"])).any()


@pytest.mark.parametrize("prog, cmd", [("vcprep", "warp"), ("vcprep", "backproject"), ("vctrain", "predict")])
def test_help_says_what_ego_rows_do(prog, cmd):
    proc = run_cli(cmd, "--help", prog=prog)
    assert proc.returncode == 0 and "ego_rows" in proc.stdout and "Example" in proc.stdout


def test_virtual_camera_design_sees_the_camera_as_cropped():
    from vcprep.camera import design_virtual_camera

    cam = replace(PRESETS["camvid"], name="rig", ego_rows=200)
    a = design_virtual_camera([cam, PRESETS["kitti"]], above=8)
    b = design_virtual_camera([cam.without_ego(), PRESETS["kitti"]], above=8)
    full = design_virtual_camera([replace(cam, ego_rows=0), PRESETS["kitti"]], above=8)
    assert a.camera == b.camera and a.camera.ego_rows == 0
    assert a.camera.size != full.camera.size  # (the ego rows would have made it taller)


def test_vp_estimation_ignores_lines_on_the_bonnet(camvid_half):
    """The rig's own vehicle can carry strong lines (panel edges, reflections). With ``ego_rows``
    the detector reads the frame as its exact bottom crop: the VP equals the one found on the
    hand-cropped image, lies at the rendered scene's VP, and the bonnet's lines (which pull the
    detection away without ego_rows) do not vote."""
    from vcprep.vp import estimate_vp

    pan, tilt = 3.0, -2.0
    img, _ = render_road(camvid_half, RoadScene(texture_seed=4), pan=pan, tilt=tilt, supersample=1)
    h, w = img.shape[:2]
    img[-EGO:] = 90
    truth = np.array(vp_from_pose(camvid_half, pan, tilt))
    decoy = truth + (0.15 * w, 0.08 * h)  # a fan of bright lines on the bonnet, aimed at a decoy VP
    for x0 in np.linspace(0, w - 1, 25):
        d = decoy - (x0, h - 1)
        x1 = x0 + d[0] * (EGO - 1) / -d[1]
        cv2.line(img, (int(round(x0)), h - 1), (int(round(x1)), h - EGO), (250, 250, 250), 2)
    ego = replace(camvid_half, ego_rows=EGO)
    with_ego = estimate_vp(img, ego)
    cropped = estimate_vp(np.ascontiguousarray(img[:-EGO]), ego.without_ego())
    assert with_ego.vp == pytest.approx(cropped.vp, abs=1e-9) and with_ego.status == cropped.status
    assert np.abs(np.array(with_ego.vp) - truth).max() < 0.01 * w
    without = estimate_vp(img, camvid_half)  # the counter-check: the bonnet's lines move the VP
    assert np.abs(np.array(without.vp) - np.array(with_ego.vp)).max() > 0.01 * w


# -- finding the own vehicle from labels (vcprep.camera.ego; issue 24.2) ----------------------------------
# Oracle: label sets drawn with a bonnet whose top row we choose, plus scene content that is
# ignored in some frames only (never in >= 90 % of them), rims, and an ornament above a gap.

def _label_set(n=12, size=(240, 160), bonnet=0, ornament=0, rims=0, seed=0, scene_ignore=True):
    """n decoded labels (0 / 1 / 255): road below the horizon, random ignored blobs in each frame
    (one frame in three also touching the bottom edge), a bonnet (an ellipse cap whose top is
    ``bonnet`` rows above the bottom, widest at the bottom edge), an ornament 3 rows above it
    ``ornament`` rows tall, and ignore rims ``rims`` columns wide up both sides."""
    from vcprep.labels import IGNORE
    w, h = size
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        lab = np.zeros((h, w), np.uint8)
        lab[h // 2:] = 1
        if scene_ignore:
            for _ in range(3):
                x, y = int(rng.integers(0, w)), int(rng.integers(0, h))
                cv2.circle(lab, (x, y), int(rng.integers(3, 20)), IGNORE, -1)
            if i % 3 == 0:
                cv2.circle(lab, (int(rng.integers(0, w)), h - 1), 25, IGNORE, -1)
        if bonnet:
            cv2.ellipse(lab, (w // 2, h - 1), (w // 2 + 10, bonnet - 1), 0, 180, 360, IGNORE, -1)
        if ornament:
            top = h - bonnet - 3 - ornament
            lab[top:top + ornament, w // 2 - 2:w // 2 + 3] = IGNORE
        if rims:
            lab[:, :rims] = IGNORE
            lab[:, -rims:] = IGNORE
        out.append(lab)
    return out


@pytest.mark.parametrize("bonnet", [12, 30, 57])
def test_ego_rows_from_labels_is_the_bonnet_top(bonnet):
    from vcprep.camera import ego_rows_from_labels
    est = ego_rows_from_labels(_label_set(bonnet=bonnet, seed=bonnet))
    assert est.rows == bonnet and est.size == (240, 160) and est.frames == 12
    assert "bottom 57 of 160 rows" in ego_rows_from_labels(_label_set(bonnet=57)).describe()


def test_no_own_vehicle_gives_0_despite_ignored_scene_content():
    from vcprep.camera import ego_rows_from_labels
    for seed in range(5):
        est = ego_rows_from_labels(_label_set(n=20, seed=seed))
        assert est.rows == 0, seed
    assert "no own vehicle" in est.describe()


def test_ornament_above_a_gap_and_rims_up_the_sides():
    from vcprep.camera import ego_rows_from_labels
    assert ego_rows_from_labels(_label_set(bonnet=20, ornament=6)).rows == 20 + 3 + 6  # the ornament counts
    assert ego_rows_from_labels(_label_set(bonnet=20, rims=4)).rows == 20              # rims do not
    assert ego_rows_from_labels(_label_set(rims=4)).rows == 0


def test_the_vehicle_must_be_common_to_the_frames():
    """A bonnet-shaped ignore region in fewer than 90 % of the frames is scene content."""
    from vcprep.camera import ego_rows_from_labels
    labs = _label_set(n=10, bonnet=30)[:8] + _label_set(n=2, scene_ignore=False)   # in 80 % of the frames
    assert ego_rows_from_labels(labs).rows == 0
    labs = _label_set(n=10, bonnet=30)[:9] + _label_set(n=1, scene_ignore=False)   # in 90 %
    assert ego_rows_from_labels(labs).rows == 30


def test_ego_detection_refuses_what_it_cannot_decide():
    from vcprep.camera import ego_rows_from_labels
    with pytest.raises(InputError, match="too few"):
        ego_rows_from_labels(_label_set(n=4, bonnet=20))
    with pytest.raises(InputError, match="two sizes"):
        ego_rows_from_labels(_label_set(n=3) + _label_set(n=3, size=(120, 80)))
    with pytest.raises(InputError, match="too tall"):
        ego_rows_from_labels(_label_set(bonnet=100))


def test_ego_rows_at_another_height_cover_the_vehicle():
    from vcprep.camera import EgoEstimate, rows_at_height
    est = EgoEstimate(36, (480, 360), 10, 0.5)
    assert rows_at_height(est, 360) == 36 and rows_at_height(est, 720) == 72
    assert rows_at_height(est, 100) == 10           # 36 * 100 / 360 = 10.0
    assert rows_at_height(est, 101) == 11           # 10.1 -> 11: never less than the vehicle
    assert rows_at_height(EgoEstimate(0, (480, 360), 10, 0.0), 720) == 0
    # the camera's own scaling rule agrees
    cam = replace(PRESETS["camvid"].for_image_size((480, 360)), ego_rows=36)
    for hh in (100, 101, 180, 720):
        assert cam.for_image_size((hh * 4 // 3, hh)).ego_rows == rows_at_height(est, hh)


def test_ego_rows_from_label_files_read_with_the_format(tmp_path):
    from vcprep.camera import ego_rows_from_label_files
    from vcprep.labels import get_label_format
    files = []
    for i, lab in enumerate(_label_set(bonnet=25)):
        ids = np.where(lab == 1, 3, np.where(lab == 255, 11, 0)).astype(np.uint8)  # CamVid ids
        files.append(tmp_path / f"f{i}.png")
        cv2.imwrite(str(files[-1]), ids)
    assert ego_rows_from_label_files(files, get_label_format("camvid")).rows == 25
    # read as a format where 11 is not ignore, nothing is common ignore
    assert ego_rows_from_label_files(files, get_label_format("values:road=3")).rows == 0


def test_vcprep_camera_ego_prints_and_writes_the_rows(tmp_path):
    labels = tmp_path / "labels" / "drive1"
    labels.mkdir(parents=True)
    for i, lab in enumerate(_label_set(bonnet=25)):
        cv2.imwrite(str(labels / f"f{i}.png"), np.where(lab == 1, 3, np.where(lab == 255, 11, 0)).astype(np.uint8))
    proc = _camera_ego("--labels", tmp_path / "labels", "--label-format", "camvid")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "25" and "bottom 25 of 160 rows" in proc.stderr
    # the camera at twice the labels' size gets the rows at its size, everything else as it was
    cam = Camera("mine", (480, 320), 400.0, 400.0, 239.5, 159.5, 1.3, tilt=2.0)
    (tmp_path / "mine.yaml").write_text(camera_to_yaml(cam))
    out = tmp_path / "cams" / "mine-ego.yaml"
    proc = _camera_ego("-l", tmp_path / "labels", "-f", "camvid", "-c", tmp_path / "mine.yaml", "-o", out,
                   "--json")
    assert proc.returncode == 0, proc.stderr
    rep = json.loads(proc.stdout)
    assert rep["ego_rows"] == 25 and rep["ego_rows_at_camera_size"] == 50 and rep["frames"] == 12
    assert read_camera_yaml(out) == replace(cam, ego_rows=50)
    # no vehicle: 0; too few frames and -o without a camera: one error line each
    for f in list(labels.iterdir()):
        cv2.imwrite(str(f), np.full((160, 240), 3, np.uint8))
    assert _camera_ego("-l", tmp_path / "labels", "-f", "camvid").stdout.strip() == "0"
    for f in list(labels.iterdir())[4:]:
        f.unlink()
    assert_one_error_line(_camera_ego("-l", tmp_path / "labels", "-f", "camvid"), "too few", "ego_rows")
    assert_one_error_line(_camera_ego("-l", tmp_path / "labels", "-f", "camvid", "-o", out),
                          "no --camera")


# -- finding the own vehicle from frames alone (vcprep.camera.ego; issue 35) -------------------------------
# Oracle: a drive rendered with varying lateral offset, pan, tilt, asphalt texture and moving boxes
# (other traffic: horizontal edges anywhere, different in every frame), and a bonnet painted as a
# fixed ellipse cap with its own shading and highlight whose top we choose.

def _drive(n=36, size=(240, 180), seed=0):
    cam = PRESETS["camvid"].for_image_size(size)
    rng = np.random.default_rng(seed)
    w, h = size
    out = []
    for i in range(n):
        img, _ = render_road(cam, RoadScene(offset=float(rng.uniform(-1.5, 1.5)), texture_seed=100 * seed + i),
                             pan=float(rng.uniform(-3, 3)), tilt=float(rng.uniform(-2, 2)), supersample=1)
        for _ in range(6):
            x, y = int(rng.integers(0, w)), int(rng.integers(0, h))
            cv2.rectangle(img, (x, y), (x + int(rng.integers(10, 60)), y + int(rng.integers(10, 40))),
                          tuple(int(c) for c in rng.integers(0, 255, 3)), -1)
        out.append(img)
    return out


def _paint_bonnet(img, rows):
    """A bonnet whose top is ``rows`` rows above the bottom edge, the same in every frame."""
    h, w = img.shape[:2]
    mask = np.zeros((h, w), np.uint8)
    cv2.ellipse(mask, (w // 2, h - 1), (3 * w // 4, rows - 1), 0, 180, 360, 255, -1)
    paint = np.broadcast_to(np.linspace(70, 30, h)[:, None, None] * np.array([1.2, 1.0, 0.9]), img.shape).copy()
    cv2.line(paint, (w // 4, h - rows // 2), (3 * w // 4, h - rows // 2 - 3), (160, 150, 140), 2)
    out = img.copy()
    out[mask > 0] = paint[mask > 0].astype(np.uint8)
    return out


@pytest.fixture(scope="module")
def drive():
    return _drive()


@pytest.mark.parametrize("bonnet", [12, 25, 40])
def test_ego_rows_from_frames_is_the_bonnet_top(drive, bonnet):
    from vcprep.camera import ego_rows_from_frames
    est = ego_rows_from_frames(_paint_bonnet(f, bonnet) for f in drive)
    assert abs(est.rows - bonnet) <= 2 and est.size == (240, 180) and est.method == "frames"
    assert est.to_dict()["method"].startswith("frames") and "found from the frames" in est.describe()


def test_frames_without_a_vehicle_give_0(drive):
    from vcprep.camera import ego_rows_from_frames
    for seed in (0, 1):
        est = ego_rows_from_frames(drive if seed == 0 else _drive(seed=seed))
        assert est.rows == 0, seed
    assert "no own vehicle" in est.describe() and est.to_dict()["method"].startswith("frames")


def test_ego_rows_from_frames_refuses_repeats_and_two_sizes(drive):
    from vcprep.camera import ego_rows_from_frames
    with pytest.raises(InputError, match="distinct frame"):   # a stopped car: every edge would stay put
        ego_rows_from_frames([_paint_bonnet(drive[0], 20)] * 40)
    with pytest.raises(InputError, match="two sizes"):
        ego_rows_from_frames(drive[:3] + [cv2.resize(drive[3], (120, 90))])


def test_vcprep_camera_ego_without_labels_uses_the_frames(drive, tmp_path):
    for i, f in enumerate(drive):
        cv2.imwrite(str(tmp_path / f"f{i:03d}.png"), _paint_bonnet(f, 25))
    proc = _camera_ego("--images", tmp_path, "--json")
    assert proc.returncode == 0, proc.stderr
    rep = json.loads(proc.stdout)
    assert abs(rep["ego_rows"] - 25) <= 2 and rep["method"].startswith("frames")
    assert "no labels" in proc.stderr and "from the frames" in proc.stderr
    assert_one_error_line(_camera_ego(), "no --labels and no --images")


def _mirror_bonnet(img, rows, gain):
    """A bonnet that reflects the scene (Cityscapes'): its cap shows the frame's upper part upside down at
    ``gain`` of its brightness, so its top edge is darker or brighter than the road above from frame
    to frame (the edge changes sign), as a polished bonnet's does."""
    h, w = img.shape[:2]
    mask = np.zeros((h, w), np.uint8)
    cv2.ellipse(mask, (w // 2, h - 1), (3 * w // 4, rows - 1), 0, 180, 360, 255, -1)
    sky = cv2.resize(img[: h // 3][::-1], (w, h))
    out = img.copy()
    out[mask > 0] = np.clip(sky[mask > 0].astype(np.float32) * gain, 0, 255).astype(np.uint8)
    return out


def test_a_missed_own_vehicle_is_a_warning_even_under_quiet(tiny_model, drive, tmp_path):
    """The search from frames misses a bonnet that reflects the scene (its edge changes sign: no
    persistent gradient); vctrain predict then says so on stderr even under --quiet, with the flag
    that states the vehicle. A painted bonnet is found and nothing is said under --quiet; --ego 0
    ends the warning."""
    from vcprep.camera import ego_rows_from_frames

    rng = np.random.default_rng(5)
    mirrored = [_mirror_bonnet(f, 25, float(rng.choice([0.4, 1.8]) * rng.uniform(0.8, 1.2))) for f in drive]
    assert ego_rows_from_frames(mirrored).rows == 0  # what the search cannot see (docs/cameras.md)
    cam = replace(PRESETS["camvid"].for_image_size(drive[0].shape[1::-1]), name="rig")
    (tmp_path / "cam.yaml").write_text(camera_to_yaml(cam))
    for name, frames in (("mirror", mirrored), ("painted", [_paint_bonnet(f, 25) for f in drive])):
        (tmp_path / name).mkdir()
        for i, f in enumerate(frames):
            cv2.imwrite(str(tmp_path / name / f"f_{i:03d}.png"), f)
    proc = run_cli("predict", tiny_model, "--camera", tmp_path / "cam.yaml", tmp_path / "mirror", "--out",
                   tmp_path / "o1", "--within", "none", "--quiet", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "warning: own vehicle: none found from the frames" in lines[0], proc.stderr
    assert "--ego N" in lines[0] and "reflects" in lines[0] and str(tmp_path / "mirror") in lines[0]
    proc = run_cli("predict", tiny_model, "--camera", tmp_path / "cam.yaml", tmp_path / "painted", "--out",
                   tmp_path / "o2", "--within", "none", "--quiet", prog="vctrain")
    assert proc.returncode == 0 and proc.stderr.strip() == "", proc.stderr
    proc = run_cli("predict", tiny_model, "--camera", tmp_path / "cam.yaml", tmp_path / "mirror", "--out",
                   tmp_path / "o3", "--within", "none", "--quiet", "--ego", "0", prog="vctrain")
    assert proc.returncode == 0 and proc.stderr.strip() == "", proc.stderr


# -- the own vehicle cut by a model that reads frames as they are (issue 60: the shipped model) ------------

def test_a_camera_file_that_states_no_own_vehicle_is_not_searched_nor_warned(tiny_model, drive, tmp_path):
    """'ego_rows: 0' written in the camera file says the frames show no own vehicle (a KITTI rig): no
    search, no warning, the summary line names the camera's ego_rows; it survives a YAML round trip
    and leaves the camera's identity (equality, records) as it was (issue 80)."""
    from vcprep.camera import read_camera_yaml

    cam = replace(PRESETS["camvid"].for_image_size(drive[0].shape[1::-1]), name="rig")
    (tmp_path / "cam.yaml").write_text(camera_to_yaml(cam) + "ego_rows: 0\n")
    stated = read_camera_yaml(tmp_path / "cam.yaml")
    assert stated.ego_stated and stated == cam and stated.to_dict() == cam.to_dict()
    (tmp_path / "again.yaml").write_text(camera_to_yaml(stated))
    assert read_camera_yaml(tmp_path / "again.yaml").ego_stated
    import pathlib

    from vcprep.camera import read_kitti_calib

    kitti = pathlib.Path(__file__).resolve().parent.parent / "examples" / "kitti" / "calib" / "um_000000.txt"
    assert PRESETS["kitti"].ego_stated and read_kitti_calib(kitti).ego_stated  # KITTI's rig shows none
    assert not PRESETS["camvid"].ego_stated
    (tmp_path / "f").mkdir()
    for i, f in enumerate(drive):  # frames without a vehicle: the search would find none and warn
        cv2.imwrite(str(tmp_path / "f" / f"f_{i:03d}.png"), f)
    proc = run_cli("predict", tiny_model, "--camera", tmp_path / "cam.yaml", tmp_path / "f", "--out", tmp_path / "o",
                   "--within", "none", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert "warning" not in proc.stderr and "none found" not in proc.stderr, proc.stderr
    assert proc.stderr.count("own vehicle") == 1 and "own vehicle: none (the camera's ego_rows)" in proc.stderr


@pytest.fixture(scope="module")
def resize_model(tiny_model, tmp_path_factory):
    """The tiny model's resize twin (width 4, 2 epochs), trained from its training store."""
    from vctrain.training import TrainConfig, fit

    root = tmp_path_factory.mktemp("ego_resize")
    fit(TrainConfig(stores=[str(tiny_model.parent / "store")], out=str(root / "rs.pt"), baseline="resize",
                    size=(64, 48), base_width=4, epochs=2, batch_size=2, val_fraction=0, progress=False, device="cpu"))
    return root / "rs.pt"


def test_a_resize_model_cuts_the_own_vehicle_only_when_asked(resize_model, drive, tmp_path):
    """A dashcam drive whose bonnet top is 25 rows up: by default (and --ego none) a resize model
    predicts every row as before; --ego auto finds the bonnet from the frames (said on stderr) and
    predicts 'not road' below its top, the rows above unchanged; --ego 30 cuts 30 rows."""
    frames = tmp_path / "dashcam"
    frames.mkdir()
    for i, f in enumerate(drive):
        cv2.imwrite(str(frames / f"d{i:02d}.png"), _paint_bonnet(f, 25))
    outs = {}
    for ego in (None, "none", "auto", "30"):
        out = tmp_path / f"pred_{ego}"
        proc = run_cli("predict", resize_model, frames, "--out", out, *(["--ego", ego] if ego else []), prog="vctrain")
        assert proc.returncode == 0, proc.stderr
        outs[ego] = (proc.stderr, [(_png(out / f"d{i:02d}_prob.png"), _png(out / f"d{i:02d}_mask.png"))
                                   for i in (0, 17, 35)])
    base = outs[None][1]
    assert all(np.array_equal(a, b) for pa, pb in zip(base, outs["none"][1]) for a, b in zip(pa, pb))
    assert "own vehicle" not in outs[None][0]
    assert any(prob[-25:].any() for prob, _ in base)  # there was road predicted on the bonnet to cut
    said = outs["auto"][0]
    rows = int(said.split("own vehicle: ")[1].split(" rows")[0])
    assert abs(rows - 25) <= 2 and "found from the frames" in said
    for cut, n in ((outs["auto"][1], rows), (outs["30"][1], 30)):
        for (prob0, mask0), (prob, mask) in zip(base, cut):
            assert not prob[-n:].any() and not mask[-n:].any()
            assert np.array_equal(prob[:-n], prob0[:-n]) and np.array_equal(mask[:-n], mask0[:-n])


# -- the own vehicle per source (issue 72.4) ---------------------------------------------------------------

def test_sources_are_grouped_by_folder_then_bdd_then_camvid_names(tmp_path):
    from vcprep.camera import source_groups
    rule, g = source_groups([tmp_path / "a" / "x.png", tmp_path / "b" / "x.png", tmp_path / "a" / "y.png"])
    assert rule.startswith("folder") and {k: len(v) for k, v in g.items()} == {str(tmp_path / "a"): 2,
                                                                                 str(tmp_path / "b"): 1}
    rule, g = source_groups([tmp_path / n for n in ("0a0a0b1a-7c39d841.jpg", "0a0a0b1a-27d9fc44.jpg",
                                                    "0a0c3694-24b5193a.jpg")])
    assert rule.startswith("BDD100K") and sorted(g) == ["0a0a0b1a", "0a0c3694"] and len(g["0a0a0b1a"]) == 2
    rule, g = source_groups([tmp_path / n for n in ("0001TP_006690.png", "0016E5_07959.png", "0001TP_006720.png")])
    assert rule.startswith("CamVid") and sorted(g) == ["0001TP", "0016E5"]
    for names in (("f_001.png", "f_002.png"), ("a.png", "b.png"), ("0001TP_1.png", "b.png")):  # one source
        rule, g = source_groups([tmp_path / n for n in names])
        assert rule == "one source" and len(g) == 1 and len(next(iter(g.values()))) == 2


def test_a_mixed_folder_gets_each_sources_own_vehicle(resize_model, drive, tmp_path):
    """Two dashcams in one folder (BDD100K-style names), bonnet tops 12 and 30 rows up, and a third
    source of one frame: --ego auto says the rule, finds 12 and 30 (one --ego N could fit neither) and
    cuts each source's frames at its own rows; the one-frame source is named as not searched, its
    frame predicted as with --ego none."""
    frames = tmp_path / "mixed"
    frames.mkdir()
    for i, f in enumerate(drive):
        src, rows = ("aaaaaaaa", 12) if i % 2 else ("bbbbbbbb", 30)
        cv2.imwrite(str(frames / f"{src}-{i:08x}.png"), _paint_bonnet(f, rows))
    cv2.imwrite(str(frames / "cccccccc-00000000.png"), _paint_bonnet(drive[0], 20))
    runs = {}
    for ego in ("none", "auto"):
        proc = run_cli("predict", resize_model, frames, "--out", tmp_path / ego, "--ego", ego, prog="vctrain")
        assert proc.returncode == 0, proc.stderr
        runs[ego] = proc.stderr
    said = runs["auto"]
    assert "3 sources grouped by BDD100K-style source prefix" in said, said
    found = {s: int(said.split(f"own vehicle of {s} (18 frames): ")[1].split(" rows")[0])
             for s in ("aaaaaaaa", "bbbbbbbb")}
    assert abs(found["aaaaaaaa"] - 12) <= 2 and abs(found["bbbbbbbb"] - 30) <= 2, said
    assert "warning: own vehicle not searched in 1 source of 3 (cccccccc; 1 frame)" in said and "--ego N" in said
    for stem, n in (("aaaaaaaa-00000001", found["aaaaaaaa"]), ("bbbbbbbb-00000002", found["bbbbbbbb"])):
        prob0, prob = _png(tmp_path / "none" / f"{stem}_prob.png"), _png(tmp_path / "auto" / f"{stem}_prob.png")
        assert not prob[-n:].any() and np.array_equal(prob[:-n], prob0[:-n]), stem
    one = "cccccccc-00000000_prob.png"
    assert np.array_equal(_png(tmp_path / "none" / one), _png(tmp_path / "auto" / one))


def test_a_night_drive_finds_its_dashboard_or_says_it_could_not(drive):
    """Night frames (a tenth of the day's light): a dark dashboard 30 rows high is found as by day; with
    no vehicle the search says it could not tell (the bottom is dark), not that there is none."""
    from vcprep.camera import ego_rows_from_frames
    night = [(f * 0.1).astype(np.uint8) for f in drive]
    dash = [f.copy() for f in night]
    for f in dash:
        f[-30:] = 3
    assert abs(ego_rows_from_frames(dash).rows - 30) <= 2
    est = ego_rows_from_frames(night)
    assert est.rows == 0 and "could not tell" in est.describe() and "dark" in est.describe()
    assert "no own vehicle" in ego_rows_from_frames(drive).describe()  # by day: none, as before
