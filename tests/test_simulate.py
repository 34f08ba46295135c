"""`vcprep simulate` against an independent oracle: the synthetic road rendered directly through
the camera the simulation claims to produce (vcprep.synthetic ray-traces any camera at any pose)."""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from conftest import assert_one_error_line, run_cli, write_synthetic_dataset
from vcprep.dataset import Job, list_dataset
from vcprep.camera import PRESETS, Camera, load_camera
from vcprep.errors import InputError
from vcprep.warp import vp_from_pose
from vcprep.labels import get_label_format
from vcprep.simulate import (SimulateParams, covered, draw_offsets, plan_simulation, recorded_homographies,
                             relative_rotation, simulate_arrays,
                             simulate_dataset)
from vcprep.synthetic import RoadScene, render_road
from vcprep.warp import source_coordinates

SCENE = RoadScene(offset=0.4, texture_seed=3)
# the source: camvid at the 480x360 release size, at a non-zero nominal pose
SRC = PRESETS["camvid"].for_image_size((480, 360)).with_pose(pan=2.0, tilt=1.0)
SS = 2  # render supersampling (anti-aliasing of the oracle)


def _interior(mask: np.ndarray, r: int = 2) -> np.ndarray:
    return cv2.erode(mask.astype(np.uint8), np.ones((2 * r + 1, 2 * r + 1), np.uint8)).astype(bool)


def _edge_band(lab: np.ndarray) -> np.ndarray:
    k = np.ones((3, 3), np.uint8)
    return cv2.dilate(lab, k) != cv2.erode(lab, k)


def _read_csv(path: Path) -> dict[str, list[float]]:
    with open(path) as f:
        rows = list(csv.reader(f))
    return {r[0]: [float(x) for x in r[1:]] for r in rows[1:]}


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """One rendered source frame (CamVid-format label: 3 road, 0 else) on disk."""
    d = tmp_path_factory.mktemp("src")
    img, lab = render_road(SRC, SCENE, supersample=SS)
    (d / "images").mkdir()
    (d / "labels").mkdir()
    cv2.imwrite(str(d / "images" / "f_0001.png"), img)
    cv2.imwrite(str(d / "labels" / "f_0001.png"), np.where(lab == 1, 3, 0).astype(np.uint8))
    return d, img, lab


def _expected_camera(size, hfov, shift) -> Camera:
    """The output camera written out by hand: focal from the edge-to-edge hfov, pixel aspect kept."""
    W, H = size
    fx = W / (2 * math.tan(math.radians(hfov) / 2))
    return Camera("exp", (W, H), fx, fx * SRC.fy / SRC.fx, (W - 1) / 2, (H - 1) / 2 + shift, SRC.height)


def _simulate(source, out, **kw):
    d = source[0]
    fmt = get_label_format("camvid")
    jobs = list_dataset(d / "images", d / "labels", fmt)
    return simulate_dataset(jobs, SRC, out, SimulateParams(**kw), fmt, progress=False)


# pan AND tilt changes on a source that is itself panned and tilted: a sign error anywhere fails
TELE = dict(size=(320, 240), hfov=35.0, pan=-5.0, tilt=3.0, horizon_shift=10.0)


def test_simulated_images_match_direct_render(source, tmp_path):
    plan, summary = _simulate(source, tmp_path / "out", **TELE)
    assert summary.written == 1
    exp = _expected_camera((320, 240), 35.0, 10.0)
    pan1, tilt1 = SRC.pan - 5.0, SRC.tilt + 3.0
    ref_img, ref_lab = render_road(exp, SCENE, pan=pan1, tilt=tilt1, supersample=SS)
    img = cv2.imread(str(tmp_path / "out/images/f_0001.png"), cv2.IMREAD_UNCHANGED)
    lab = cv2.imread(str(tmp_path / "out/labels/f_0001.png"), cv2.IMREAD_UNCHANGED)
    assert img.shape == (240, 320, 3) and lab.shape == (240, 320)
    # image: the road texture (about 40 grey levels of contrast) agrees away from the road edge
    road = _interior(ref_lab == 1)
    assert road.sum() > 3000
    diff = np.abs(img.astype(float) - ref_img.astype(float))[road].mean()
    assert diff < 2.5, diff
    # label: raw CamVid ids kept, identical except on the 1-px band along the road edge
    assert set(np.unique(lab)) <= {0, 3}
    disagree = ((lab == 3) != (ref_lab == 1)) & ~_edge_band(ref_lab)
    assert disagree.sum() == 0, disagree.sum()
    # VP: the exact VP of the new camera at the new pose
    vp = _read_csv(tmp_path / "out/vps.csv")["f_0001"]
    np.testing.assert_allclose(vp, vp_from_pose(exp, pan1, tilt1), atol=1e-6)
    pose = _read_csv(tmp_path / "out/poses.csv")["f_0001"]
    np.testing.assert_allclose(pose, [pan1, tilt1, 0.0], atol=1e-6)
    # camera.yaml: loads, and is the expected camera at the new pose (written to 6 significant digits)
    cam = load_camera(tmp_path / "out/camera.yaml")
    assert cam.size == (320, 240)
    np.testing.assert_allclose([cam.fx, cam.fy, cam.cx, cam.cy], [exp.fx, exp.fy, exp.cx, exp.cy], rtol=1e-5)
    np.testing.assert_allclose([cam.pan, cam.tilt, cam.height], [pan1, tilt1, SRC.height], atol=1e-5)
    assert abs(cam.fov_deg()[0] - 35.0) < 1e-3
    meta = json.loads((tmp_path / "out/simulate.json").read_text())
    assert meta["complete"] and meta["fov_auto"] is False and meta["parameters"]["tilt"] == 3.0


def test_wrong_sign_would_be_detected(source):
    """The tolerances above mean something: the opposite pan or tilt change is far off."""
    d, img, _ = source
    exp = _expected_camera((320, 240), 35.0, 10.0)
    ref_img, ref_lab = render_road(exp, SCENE, pan=SRC.pan - 5.0, tilt=SRC.tilt + 3.0, supersample=SS)
    road = _interior(ref_lab == 1)
    for dpan, dtilt in ((5.0, 3.0), (-5.0, -3.0)):
        R = relative_rotation(SRC.pan, SRC.tilt, SRC.pan + dpan, SRC.tilt + dtilt)
        wrong, _ = simulate_arrays(img, None, exp.K @ R @ np.linalg.inv(SRC.K), exp.size)
        assert np.abs(wrong.astype(float) - ref_img.astype(float))[road].mean() > 8.0


def test_flip_is_the_mirrored_camera(source, tmp_path):
    plan, _ = _simulate(source, tmp_path / "plain", **TELE)
    fplan, _ = _simulate(source, tmp_path / "flip", **TELE, flip=True)
    W = 320
    a = cv2.imread(str(tmp_path / "plain/images/f_0001.png"))
    b = cv2.imread(str(tmp_path / "flip/images/f_0001.png"))
    assert np.abs(b[:, ::-1].astype(int) - a.astype(int)).max() <= 1
    # the VP mirrors exactly; pan changes sign, tilt is kept
    u, v = _read_csv(tmp_path / "plain/vps.csv")["f_0001"]
    fu, fv = _read_csv(tmp_path / "flip/vps.csv")["f_0001"]
    assert abs(fu - (W - 1 - u)) < 1e-6 and abs(fv - v) < 1e-6
    cam = load_camera(tmp_path / "flip/camera.yaml")
    assert abs(cam.pan - -(SRC.pan - 5.0)) < 1e-5 and abs(cam.tilt - (SRC.tilt + 3.0)) < 1e-5
    # oracle: the mirrored world (road offset -0.4) seen at the mirrored pan gives the flipped label
    exp = _expected_camera((320, 240), 35.0, 10.0)
    _, ref_lab = render_road(exp, RoadScene(offset=-SCENE.offset), pan=-(SRC.pan - 5.0), tilt=SRC.tilt + 3.0,
                             supersample=1)
    lab = cv2.imread(str(tmp_path / "flip/labels/f_0001.png"), cv2.IMREAD_UNCHANGED)
    assert (((lab == 3) != (ref_lab == 1)) & ~_edge_band(ref_lab)).sum() == 0


def _blank_jobs(folder: Path, size, n: int) -> list[Job]:
    folder.mkdir(parents=True, exist_ok=True)
    jobs = []
    for i in range(n):
        p = folder / f"s_{i:03d}.png"
        cv2.imwrite(str(p), np.zeros((size[1], size[0]), np.uint8))
        jobs.append(Job(p.stem, p))
    return jobs


def test_roll_turns_the_picture_clockwise(tmp_path):
    """Square pixels: the principal point stays, and a point right of it moves DOWN by the angle."""
    cam = Camera("sq", (160, 120), 150.0, 150.0, 79.5, 59.5, 1.4)
    img = np.zeros((120, 160), np.uint8)
    cv2.circle(img, (120, 60), 3, 255, -1)  # a dot 40.5 px right of the principal point (and 0.5 px below)
    dot = np.array([120.0, 60.0])
    for roll in (6.0, -6.0):
        plan = plan_simulation(_blank_jobs(tmp_path / "r", (160, 120), 1), cam, SimulateParams(roll=roll))
        it = plan.items[0]
        z = plan.zoom
        assert 1.0 < z < 1.3 and plan.camera.cx == 79.5 and plan.camera.cy == 59.5
        np.testing.assert_allclose(it.out_H_src @ [79.5, 59.5, 1.0] / (it.out_H_src[2] @ [79.5, 59.5, 1.0]),
                                   [79.5, 59.5, 1.0], atol=1e-9)
        out, _ = simulate_arrays(img, None, it.out_H_src, plan.camera.size)
        ys, xs = np.nonzero(out > 0)
        w = out[ys, xs].astype(float)
        centroid = np.array([(xs * w).sum() / w.sum(), (ys * w).sum() / w.sum()])
        r = math.radians(roll)
        rel = dot - [79.5, 59.5]
        expect = np.array([79.5, 59.5]) + z * np.array([rel[0] * math.cos(r) - rel[1] * math.sin(r),
                                                        rel[0] * math.sin(r) + rel[1] * math.cos(r)])
        np.testing.assert_allclose(centroid, expect, atol=0.15)
        assert (centroid[1] > 59.5 + z * 0.5 + 3) == (roll > 0)  # moved down (clockwise on screen) for roll > 0
        assert plan.notes and "no roll" in plan.notes[0]
        assert it.pose[2] == roll
        assert covered(np.linalg.inv(it.out_H_src), cam.size, plan.camera.size)
        assert not covered(np.linalg.inv(it.out_H_src), cam.size, (180, 120))  # a wider view leaves the source


JITTER = dict(size=(400, 200), pan=4.0, tilt=-2.0, roll=1.0, pan_jitter=8.0, tilt_jitter=4.0, roll_jitter=3.0, seed=7)


def test_auto_fov_is_the_widest_fully_covered(tmp_path):
    jobs = _blank_jobs(tmp_path / "b", (480, 360), 6)
    plan = plan_simulation(jobs, SRC, SimulateParams(**JITTER))
    assert plan.fov_auto and len({it.draw for it in plan.items}) == 6
    for it in plan.items:
        x, y, front = source_coordinates(np.linalg.inv(it.out_H_src), plan.camera.size)
        assert front.all()
        assert x.min() >= -1e-6 and x.max() <= 479 + 1e-6 and y.min() >= -1e-6 and y.max() <= 359 + 1e-6
    hfov = plan.fov_deg[0]
    # tight: some image touches its source border...
    margins = [min(x.min(), 479 - x.max(), y.min(), 359 - y.max())
               for x, y, _ in (source_coordinates(np.linalg.inv(it.out_H_src), plan.camera.size) for it in plan.items)]
    assert min(margins) < 1e-3
    # ...so a slightly wider view is refused, naming the widest that works, which is accepted
    with pytest.raises(InputError) as e:
        plan_simulation(jobs, SRC, SimulateParams(**JITTER, hfov=hfov + 0.05))
    assert f"--hfov {math.floor(hfov * 100) / 100:.2f} or less" in str(e.value)
    ok = plan_simulation(jobs, SRC, SimulateParams(**JITTER, hfov=math.floor(hfov * 100) / 100))
    assert not ok.fov_auto and ok.zoom >= plan.zoom


def test_draws_are_reproducible_independent_and_bounded(tmp_path):
    a = draw_offsets(7, "img_1", 8.0, 4.0, 3.0)
    assert a == draw_offsets(7, "img_1", 8.0, 4.0, 3.0)
    assert a != draw_offsets(8, "img_1", 8.0, 4.0, 3.0) and a != draw_offsets(7, "img_2", 8.0, 4.0, 3.0)
    # one jitter does not change another's draw
    assert draw_offsets(7, "img_1", 8.0, 0.0, 0.0)[0] == a[0]
    draws = np.array([draw_offsets(3, f"x{i}", 8.0, 4.0, 3.0) for i in range(400)])
    assert np.all(np.abs(draws) <= [8.0, 4.0, 3.0])
    assert np.all(np.abs(draws).max(axis=0) > [7.5, 3.7, 2.8])  # really spread over the range
    # in a plan: the draw of an image does not depend on the other images
    jobs = _blank_jobs(tmp_path / "j", (480, 360), 4)
    full = plan_simulation(jobs, SRC, SimulateParams(**JITTER, hfov=20.0))
    part = plan_simulation(jobs[2:3], SRC, SimulateParams(**JITTER, hfov=20.0))
    assert part.items[0].draw == full.items[2].draw
    np.testing.assert_allclose(part.items[0].out_H_src, full.items[2].out_H_src)


def test_given_vps_are_mapped_through_h(source, tmp_path):
    d = source[0]
    (tmp_path / "vps.csv").write_text("id,u,v\nf_0001,250.25,170.5\n")
    jobs = list_dataset(d / "images")
    plan, _ = simulate_dataset(jobs, SRC, tmp_path / "o", SimulateParams(**TELE), vps_file=tmp_path / "vps.csv",
                               progress=False)
    H = plan.items[0].out_H_src
    p = H @ [250.25, 170.5, 1.0]
    np.testing.assert_allclose(_read_csv(tmp_path / "o/vps.csv")["f_0001"], p[:2] / p[2], atol=1e-6)
    assert plan.items[0].vp_status == "given"


def test_recorded_homographies_reproduce_every_written_label(source, tmp_path):
    """The H recorded per item carries the source label onto the label simulate wrote, pixel for
    pixel, jitter included; it is the plan's matrix exactly (JSON keeps every float)."""
    d = source[0]
    for k in range(2):  # a second frame, so each item has its own jittered H
        cv2.imwrite(str(d / "images" / f"g_{k}.png"), source[1])
        cv2.imwrite(str(d / "labels" / f"g_{k}.png"), np.where(source[2] == 1, 3, 0).astype(np.uint8))
    try:
        plan, _ = _simulate(source, tmp_path / "o", size=(320, 240), hfov=40.0, pan_jitter=6.0, tilt_jitter=3.0, seed=4)
        rec = recorded_homographies(tmp_path / "o")
        assert sorted(rec) == sorted(it.job.id for it in plan.items)
        Hs = [rec[it.job.id] for it in plan.items]
        assert not np.allclose(Hs[0], Hs[1])  # per-item draws
        for it in plan.items:
            np.testing.assert_array_equal(rec[it.job.id], it.out_H_src)
            src_lab = cv2.imread(str(it.job.label), cv2.IMREAD_UNCHANGED)
            mine = simulate_arrays(src_lab, src_lab, rec[it.job.id], plan.camera.size)[1]
            written = cv2.imread(str(tmp_path / "o" / "labels" / it.job.label.name), cv2.IMREAD_UNCHANGED)
            np.testing.assert_array_equal(mine, written)
    finally:
        for k in range(2):
            (d / "images" / f"g_{k}.png").unlink()
            (d / "labels" / f"g_{k}.png").unlink()


def test_recorded_homographies_refuse_a_missing_or_unfinished_record(source, tmp_path):
    with pytest.raises(InputError, match="no simulate.json"):
        recorded_homographies(tmp_path)
    _simulate(source, tmp_path / "o", size=(320, 240), hfov=40.0)
    meta = tmp_path / "o" / "simulate.json"
    doc = json.loads(meta.read_text())
    meta.write_text(json.dumps({**doc, "complete": False}))
    with pytest.raises(InputError, match="unfinished"):
        recorded_homographies(tmp_path / "o")
    meta.write_text("{not json")
    with pytest.raises(InputError, match="unreadable"):
        recorded_homographies(tmp_path / "o")


def test_kitti_colour_labels_keep_their_names_and_colours(tmp_path):
    cam = PRESETS["kitti"].for_image_size((310, 94))
    img, lab = render_road(cam, SCENE, supersample=1)
    (tmp_path / "im").mkdir()
    (tmp_path / "gt").mkdir()
    cv2.imwrite(str(tmp_path / "im/um_000003.png"), img)
    colours = np.where(lab[..., None] == 1, [255, 0, 255], [0, 0, 255]).astype(np.uint8)
    colours[-3:] = 0  # ignore
    cv2.imwrite(str(tmp_path / "gt/um_road_000003.png"), colours)
    fmt = get_label_format("kitti")
    jobs = list_dataset(tmp_path / "im", tmp_path / "gt", fmt)
    simulate_dataset(jobs, cam, tmp_path / "o", SimulateParams(tilt=2.0, greyscale=True), fmt, progress=False)
    again = list_dataset(tmp_path / "o/images", tmp_path / "o/labels", fmt)  # pairs by the kitti naming rule
    assert [j.label.name for j in again] == ["um_road_000003.png"]
    out_lab = cv2.imread(str(again[0].label), cv2.IMREAD_UNCHANGED)
    colours_out = {tuple(c) for c in out_lab.reshape(-1, 3)}
    assert colours_out <= {(255, 0, 255), (0, 0, 255), (0, 0, 0)} and (255, 0, 255) in colours_out
    grey = cv2.imread(str(again[0].image), cv2.IMREAD_UNCHANGED)
    assert grey.ndim == 3 and (grey[..., 0] == grey[..., 1]).all() and (grey[..., 0] == grey[..., 2]).all()


# --- the command ------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def dataset(tmp_path_factory, camvid_half):
    return write_synthetic_dataset(tmp_path_factory.mktemp("ds"), camvid_half, n=3, bonnet_rows=20)


def test_cli_writes_a_dataset_and_reruns_idempotently(dataset, tmp_path):
    imgs, labs = dataset
    out = tmp_path / "sim"
    args = ["simulate", "--camera", "camvid", "--images", imgs, "--labels", labs, "--label-format", "camvid",
            "--out", out, "--size", "240x120", "--tilt", "2", "--pan-jitter", "3", "--seed", "1"]
    p = run_cli(*args)
    assert p.returncode == 0, p.stderr
    assert p.stdout == f"{out}\n"
    assert "3 written" in p.stderr and "widest covered" in p.stderr
    jobs = list_dataset(out / "images", out / "labels", get_label_format("camvid"))
    assert [j.id for j in jobs] == ["seq_0000", "seq_0001", "seq_0002"]
    for j in jobs:
        lab = cv2.imread(str(j.label), cv2.IMREAD_UNCHANGED)
        assert lab.shape == (120, 240) and set(np.unique(lab)) <= {0, 3, 11} and (lab == 3).any()  # raw ids
    assert len(_read_csv(out / "vps.csv")) == 3 and len(_read_csv(out / "poses.csv")) == 3
    before = {f: f.read_bytes() for f in out.rglob("*") if f.is_file() and f.name != "simulate.json"}
    p2 = run_cli(*args, "--quiet")
    assert p2.returncode == 0 and p2.stdout == f"{out}\n" and p2.stderr == ""
    assert {f: f.read_bytes() for f in out.rglob("*") if f.is_file() and f.name != "simulate.json"} == before
    meta = json.loads((out / "simulate.json").read_text())
    assert meta["counts"] == {"images": 3, "labels": 3, "written": 0, "up_to_date": 3} and meta["parameters"]["seed"] == 1


def test_rerun_drops_outputs_of_removed_images_and_survives_a_corrupt_frame(dataset, tmp_path):
    imgs, labs = dataset
    fmt = get_label_format("camvid")
    jobs = list_dataset(imgs, labs, fmt)
    params = SimulateParams(size=(240, 180), hfov=40.0)
    simulate_dataset(jobs, PRESETS["camvid"], tmp_path / "o", params, fmt, progress=False)
    _, summary = simulate_dataset(jobs[:2], PRESETS["camvid"], tmp_path / "o", params, fmt, progress=False)
    assert summary.up_to_date == 2 and summary.removed == 2  # image and label of seq_0002
    assert sorted(f.name for f in (tmp_path / "o/images").iterdir()) == ["seq_0000.png", "seq_0001.png"]
    assert len(_read_csv(tmp_path / "o/vps.csv")) == 2
    # a truncated frame stops the run with its name; finished files are whole, no temp files remain
    bad = tmp_path / "bad"
    bad.mkdir()
    for j in jobs:
        (bad / j.image.name).write_bytes(j.image.read_bytes())
    (bad / "seq_0001.png").write_bytes(jobs[1].image.read_bytes()[:5000])
    with pytest.raises(InputError, match="truncated"):
        simulate_dataset(list_dataset(bad), PRESETS["camvid"], tmp_path / "p", params, progress=False)
    assert [f.name for f in (tmp_path / "p/images").iterdir()] == ["seq_0000.png"]
    assert cv2.imread(str(tmp_path / "p/images/seq_0000.png")).shape == (180, 240, 3)
    meta = json.loads((tmp_path / "p/simulate.json").read_text())
    assert meta["complete"] is False and [r["id"] for r in meta["items"]] == ["seq_0000"]
    (bad / "seq_0001.png").write_bytes(jobs[1].image.read_bytes())
    _, summary = simulate_dataset(list_dataset(bad), PRESETS["camvid"], tmp_path / "p", params, progress=False)
    assert (summary.written, summary.up_to_date) == (2, 1)
    assert json.loads((tmp_path / "p/simulate.json").read_text())["complete"] is True


def test_cli_help_has_examples():
    p = run_cli("simulate", "--help")
    assert p.returncode == 0
    assert "Example" in p.stdout and "--hfov 35 --tilt 3 --size 320x240" in p.stdout and "HEIGHT" in p.stdout


@pytest.mark.parametrize("extra, needles", [
    (["--size", "240by120"], ["--size", "WIDTHxHEIGHT"]),
    (["--hfov", "120"], ["--hfov", "or less"]),
    (["--hfov", "30", "--zoom", "2"], ["both --hfov and --zoom"]),
    (["--labels", "LABELS"], ["--label-format"]),
    (["--vps", "VPS"], ["no row for image 'seq_0001'"]),
])
def test_cli_bad_inputs_give_one_error_line(dataset, tmp_path, extra, needles):
    imgs, labs = dataset
    (tmp_path / "vps.csv").write_text("id,u,v\nseq_0000,240,180\n")
    extra = [str(labs) if a == "LABELS" else str(tmp_path / "vps.csv") if a == "VPS" else a for a in extra]
    out = tmp_path / "sim"
    p = run_cli("simulate", "--camera", "camvid", "--images", imgs, "--out", out, *extra)
    assert_one_error_line(p, *needles)
    assert not out.exists()  # nothing written


def test_cli_empty_image_folder_and_foreign_out(tmp_path, dataset):
    (tmp_path / "empty").mkdir()
    assert_one_error_line(run_cli("simulate", "-c", "camvid", "-i", tmp_path / "empty", "-o", tmp_path / "o"), "no images")
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy/notes.txt").write_text("mine")
    assert_one_error_line(run_cli("simulate", "-c", "camvid", "-i", dataset[0], "-o", tmp_path / "busy"),
                          "holds no simulate.json")
