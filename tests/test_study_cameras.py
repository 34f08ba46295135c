"""vctrain crossval: the own vehicle, estimated cameras, camera names and the shipped defaults."""
from __future__ import annotations

import json

import pytest
import yaml

from conftest import assert_one_error_line, run_cli, write_synthetic_dataset
from studies import _ego_study, _store_ego_rows, _study


@pytest.mark.parametrize("ego, rows", [(None, 8), ("auto", 8), ("none", 0), (5, 5)])
def test_the_own_vehicle_is_found_from_the_labels(tmp_path, ego, rows):
    study = _ego_study(tmp_path / "data", ego)
    out = tmp_path / "out"
    proc = run_cli("crossval", study, "--out", out, "--json", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert _store_ego_rows(out, "car") == {rows}          # every item of car is warped without its bonnet rows
    assert _store_ego_rows(out, "camvid") == {0}          # nothing found where nothing is
    found = json.loads((out / "study.json").read_text()).get("ego_found", {})
    if ego in (None, "auto"):
        assert found["car"]["ego_rows"] == 8 and found["car"]["frames"] == 6 and found["camvid"]["ego_rows"] == 0
        assert "car: own vehicle in the bottom 8 of 180 rows" in proc.stderr
    else:
        assert "car" not in found and "own vehicle in the bottom" not in proc.stderr


@pytest.mark.parametrize("ego", [-1, "maybe", True, 2.5])
def test_a_bad_ego_value_is_one_error_line(tmp_path, ego):
    proc = run_cli("crossval", _ego_study(tmp_path / "data", ego), "--out", tmp_path / "out", prog="vctrain")
    assert_one_error_line(proc, "dataset 'car' has ego", "ego: auto")


def test_camera_estimate_in_a_study(tmp_path):
    """camera: estimate -- the test camera estimated from its own frames once, kept beside the
    stores, said, noted in the table, and reused on a rerun (issue 25)."""
    import math

    from vcprep.camera import Camera, read_camera_yaml

    f = 120 / math.tan(math.radians(30))  # the assumed 60-degree lens, so the estimated tilt is the true one
    true = Camera("car", (240, 180), f, f, 119.5, 89.5, 1.4, tilt=3.0)
    root = tmp_path / "data"
    study = _ego_study(root)
    d = yaml.safe_load(study.read_text())
    images, labels = write_synthetic_dataset(root / "car_est", true, n=6, bonnet_rows=8,
                                             poses=[(p, 3.0) for p in (0, 1, -1, 0.5, -0.5, 0)])
    d["datasets"][1].update(camera="estimate", test={"images": str(images), "labels": str(labels)})
    study.write_text(yaml.safe_dump(d, sort_keys=False))
    out = tmp_path / "out"
    proc = run_cli("crossval", study, "--out", out, "--json", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    cam = read_camera_yaml(out / "cameras" / "car.yaml")
    assert cam.tilt == pytest.approx(3.0, abs=0.3) and cam.ego_rows == 8 and cam.size == (240, 180)
    assert "car: camera ESTIMATED from its frames" in proc.stderr and "fx assumed" in proc.stderr
    assert "ASSUMED" in (out / "cameras" / "car.yaml").read_text()
    assert json.loads((out / "study.json").read_text())["cameras_estimated"]["car"]["tilt"] == cam.tilt
    assert "Camera of car ESTIMATED" in (out / "table.md").read_text()
    assert _store_ego_rows(out, "car") == {8}
    proc = run_cli("crossval", study, "--out", out, "--json", prog="vctrain")  # resumes: estimated once
    assert proc.returncode == 0, proc.stderr
    assert "estimating its camera" not in proc.stderr and "camera ESTIMATED" in proc.stderr
    assert "building it afresh" not in proc.stderr and "training on" not in proc.stderr
    # the first estimate is the camera as its YAML reads back (not the unrounded one), so a resumed
    # study designs the very same virtual camera and its finished stores stay finished
    from vctrain.study import Resolution, load_study

    fresh = tmp_path / "fresh"
    first, again = (Resolution(load_study(study), fresh) for _ in range(2))
    car = load_study(study).dataset("car")
    cam1 = first.camera(car)
    assert cam1 == again.camera(car) == read_camera_yaml(fresh / "cameras" / "car.yaml")
    assert first.virtual() == again.virtual()


def test_a_study_camera_that_is_both_a_preset_and_a_folder_is_an_error_naming_both(tmp_path):
    """The one naming rule in a study (issue 26.5): a dataset folder kitti/ next to the study and
    camera: kitti is an error naming both readings; preset:kitti is the preset, ./kitti the folder."""
    from vctrain.study import load_study

    study = _study(tmp_path / "data")
    d = yaml.safe_load(study.read_text())
    (tmp_path / "data" / "kitti").mkdir()
    d["datasets"][1]["camera"] = "kitti"
    study.write_text(yaml.safe_dump(d))
    proc = run_cli("crossval", study, "--out", tmp_path / "out", prog="vctrain")
    assert_one_error_line(proc, "dataset 'kitti' camera 'kitti' is both the camera preset kitti and the folder",
                          "preset:kitti", "./kitti")
    assert not (tmp_path / "out").exists()
    d["datasets"][1]["camera"] = "preset:kitti"
    study.write_text(yaml.safe_dump(d))
    assert load_study(study).datasets[1].camera == "preset:kitti"
    d["datasets"][1]["camera"] = "./kitti"
    study.write_text(yaml.safe_dump(d))
    assert load_study(study).datasets[1].camera == str(tmp_path / "data" / "kitti")
    (tmp_path / "data" / "kitti").rmdir()
    d["datasets"][1]["camera"] = "kitti"          # no such folder: the preset
    study.write_text(yaml.safe_dump(d))
    assert load_study(study).datasets[1].camera == "preset:kitti"
    d["datasets"][1]["camera"] = "preset:nope"
    study.write_text(yaml.safe_dump(d))
    assert_one_error_line(run_cli("crossval", study, "--out", tmp_path / "out", prog="vctrain"),
                          "unknown camera preset 'nope'")


def test_a_study_that_sets_nothing_gets_the_measured_design(tmp_path):
    """No store_width/store_pixels/above/crop/canvas: the 172800-px budget, the virtual camera cropped
    to 8 deg above the horizon, its rectangle sized by the trainable cameras (canvas: footprint) and
    full-height 4/9-width training windows (issue 24's measured best);
    store_width alone still sets the scale, 'above: null' leaves the design uncropped, and an
    explicit crop wins over the default."""
    import math

    from vctrain.study import DEFAULT_ABOVE, DEFAULT_CANVAS, DEFAULT_STORE_PIXELS, Resolution, load_study, training_settings

    study = _study(tmp_path / "data")
    d = yaml.safe_load(study.read_text())
    del d["store_width"], d["above"]
    d["train"].pop("crop", None)
    study.write_text(yaml.safe_dump(d))
    s = load_study(study)
    assert s.above == DEFAULT_ABOVE == 8.0 and s.store_pixels is None and s.store_width is None
    assert s.canvas is None and DEFAULT_CANVAS == "footprint"
    b = Resolution(s, tmp_path / "out")
    assert b.canvas == "footprint"
    v = b.virtual()
    f = v.K[0][0]
    # rows above the horizon: f (tan 8 deg + tan tilt_range 3 deg)
    assert v.K[1][2] + 0.5 == pytest.approx(f * (math.tan(math.radians(8)) + math.tan(math.radians(3))), rel=1e-6)
    w, h = v.size
    assert (w * b.scale()) * (h * b.scale()) == pytest.approx(DEFAULT_STORE_PIXELS, rel=1e-9)
    assert training_settings(s)["crop"] == pytest.approx([4 / 9, 1.0])

    d["store_width"], d["above"], d["train"]["crop"] = 200, None, 0.5
    study.write_text(yaml.safe_dump(d))
    s = load_study(study)
    b = Resolution(s, tmp_path / "out2")
    assert s.above is None and b.scale() == pytest.approx(200 / b.virtual().size[0])
    assert b.virtual().size[1] > v.size[1]  # uncropped: taller than the 8-degree design
    assert training_settings(s)["crop"] == 0.5


def test_extent_median_trains_in_the_median_rectangle_and_extends_each_test_split(tmp_path):
    """extent: median over CamVid (58 deg), KITTI (81 deg) and Cityscapes: every training store
    shares the rectangle sized by the median camera (narrower than 'max', which KITTI sizes), and
    each dataset's test split gets that rectangle extended to hold its own frames at their poses, as
    vctrain predict extends it (checked: extending it once more for those views changes nothing);
    a crossval run builds and scores the test stores in their own rectangles."""
    from vcprep.camera import camera_from_dict, extend_canvas, same_camera_other_canvas
    from vcprep.store import Store
    from vctrain.study import Resolution, load_study

    study = _study(tmp_path / "data")
    d = yaml.safe_load(study.read_text())
    full = Resolution(load_study(study), tmp_path / "full").training_virtual()
    d["extent"] = "median"
    study.write_text(yaml.safe_dump(d))
    s = load_study(study)
    train = Resolution(s, tmp_path / "out").training_virtual()
    assert same_camera_other_canvas(train.to_dict(), full.to_dict()) and train.size[0] < full.size[0]
    proc = run_cli("crossval", study, "--out", tmp_path / "out", "--conditions", "within", "--heldout", "kitti",
                   "--quiet", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    stores = {split: Store.open(tmp_path / "out" / "stores" / name / split / "within")
              for name, split in (("camvid", "train"), ("kitti", "test"))}
    assert stores["train"].params["virtual"] == train.to_dict()
    test = camera_from_dict(stores["test"].params["virtual"])
    assert same_camera_other_canvas(test.to_dict(), train.to_dict()) and test.size[0] > train.size[0]  # the widest
    views = [(camera_from_dict(r["camera_params"]), r["pan_deg"], r["tilt_deg"]) for r in stores["test"]]
    assert extend_canvas(test, views) is test
    info = json.loads((tmp_path / "out" / "study.json").read_text())
    result = json.loads((tmp_path / "out" / "runs" / "kitti" / "within" / "result.json").read_text())
    assert info["extent"] == "median" and result["test_warp"]["rectangle"] == list(test.size)
    assert "| kitti |" in proc.stdout
