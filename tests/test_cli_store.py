"""The real vcprep command: store building, up-to-date logic, records, back-projection, help, and
bad inputs (one `Error:` line naming the file, exit != 0, nothing half-written)."""
from __future__ import annotations

import json
import shutil

import cv2
import numpy as np
import pytest

from vcprep.camera import PRESETS, camera_to_yaml
from vcprep.warp import virt_H_src, virtual_at_scale

from conftest import PAPER_STORE, EXAMPLES, run_here, assert_one_error_line, run_cli, write_synthetic_dataset


@pytest.fixture(scope="module")
def dataset(tmp_path_factory, camvid_half):
    root = tmp_path_factory.mktemp("ds")
    images, labels = write_synthetic_dataset(root, camvid_half, n=3, bonnet_rows=20)
    return root, images, labels


def _warp(images, labels, out, *extra):
    return run_cli("warp", "--camera", "camvid", "--images", images, "--labels", labels, "--label-format", "camvid",
                   "--out", out, *PAPER_STORE, *extra)


def _records(store):
    """The records `vcprep store show --json` prints, the command's entry point run in this process
    (conftest.run_here): the file's ~25 reads of a store each cost a new interpreter (~0.4 s); the
    commands under test (warp, backproject, ...) stay real processes."""
    proc = run_here("store", "show", store, "--json")
    assert proc.returncode == 0, proc.stderr
    return [json.loads(line) for line in proc.stdout.splitlines()]


def test_warp_builds_store_with_documented_records(dataset, tmp_path, camvid_half):
    _, images, labels = dataset
    out = tmp_path / "store"
    proc = _warp(images, labels, out, "--complete", "none")  # the bare warp (default: projective completion)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(out)
    assert "3 built, 0 up to date" in proc.stderr
    recs = _records(out)
    assert [r["id"] for r in recs] == ["seq_0000", "seq_0001", "seq_0002"]
    r = recs[0]
    for key in ("id", "source", "camera", "size", "H", "image", "label", "store_size", "valid", "vp", "vp_status",
                "pan_deg", "tilt_deg", "source_sha256"):
        assert key in r
    assert r["source"] == str(images / "seq_0000.png") and r["camera"] == "camvid" and r["size"] == [480, 360]
    assert r["store_size"] == [688, 350]
    v = virtual_at_scale(PRESETS["virtual"], 0.125)
    assert np.allclose(np.array(r["H"]).reshape(3, 3) / r["H"][8], virt_H_src(camvid_half, v) / virt_H_src(camvid_half, v)[2, 2])
    lab = cv2.imread(str(out / r["label"]), cv2.IMREAD_UNCHANGED)
    img = cv2.imread(str(out / r["image"]), cv2.IMREAD_UNCHANGED)
    valid = cv2.imread(str(out / r["valid"]), cv2.IMREAD_UNCHANGED)
    assert lab.shape == img.shape[:2] == valid.shape == (350, 688)
    assert set(np.unique(lab)) <= {0, 1, 255} and (lab == 1).sum() > 1000
    assert set(np.unique(valid)) == {0, 1}
    assert (lab[valid == 0] == 255).all() and not img[valid == 0].any()
    # the CamVid bonnet (id 11) became ignore inside the covered region
    assert ((lab == 255) & (valid == 1)).sum() > 0


def test_rerun_does_no_work_and_changes_redo_exactly_the_affected_items(dataset, tmp_path):
    root, images, labels = dataset
    imgs = tmp_path / "images"
    shutil.copytree(images, imgs)
    out = tmp_path / "store"
    assert _warp(imgs, labels, out).returncode == 0
    before = {r["id"]: r for r in _records(out)}
    mtimes = {p.name: p.stat().st_mtime_ns for p in (out / "images").iterdir()}
    proc = _warp(imgs, labels, out)
    assert "0 built, 3 up to date" in proc.stderr
    assert {p.name: p.stat().st_mtime_ns for p in (out / "images").iterdir()} == mtimes
    # change one image: exactly that item is rebuilt
    a = cv2.imread(str(imgs / "seq_0001.png"))
    cv2.imwrite(str(imgs / "seq_0001.png"), 255 - a)
    proc = _warp(imgs, labels, out)
    assert "1 built, 2 up to date" in proc.stderr, proc.stderr
    after = {r["id"]: r for r in _records(out)}
    assert after["seq_0001"]["source_sha256"] != before["seq_0001"]["source_sha256"]
    assert after["seq_0000"] == before["seq_0000"]
    # a different camera (height) changes every H: everything is redone
    cam = PRESETS["camvid"].to_dict()
    cam["height"] = 1.5
    cam_file = tmp_path / "cam.yaml"
    from vcprep.camera import camera_from_dict
    cam_file.write_text(camera_to_yaml(camera_from_dict(cam)))
    proc = run_cli("warp", "--camera", cam_file, "--images", imgs, "--labels", labels, "--label-format", "camvid",
                   "--out", out)
    assert "3 built, 0 up to date" in proc.stderr, proc.stderr
    # a different scale into the same store is refused, and nothing changes
    proc = _warp(imgs, labels, out, "--scale", "0.25")
    assert_one_error_line(proc, str(out), "scale")
    assert len(_records(out)) == 3


def test_warp_into_a_store_of_frames_says_what_it_held_and_names_both_cameras(dataset, tmp_path):
    """Issue 80: another day's frames warped into the training store by mistake printed only "49 items: 49
    built". Now the summary says how many items the store held before, and frames of another camera than
    its own (both YAMLs named after their file: 'camera') get one warning naming both, even under -q."""
    root, images, labels = dataset
    out = tmp_path / "store"
    day1, day2 = tmp_path / "day1", tmp_path / "day2"
    for day, height in ((day1, 1.21), (day2, 1.5)):
        (day / "images").mkdir(parents=True)
        (day / "labels").mkdir()
        for p in images.iterdir():
            shutil.copy(p, day / "images" / f"{day.name}_{p.name}")
            shutil.copy(labels / p.name, day / "labels" / f"{day.name}_{p.name}")
        from vcprep.camera import camera_from_dict
        (day / "camera.yaml").write_text(camera_to_yaml(camera_from_dict({**PRESETS["camvid"].to_dict(),
                                                                           "name": "camera", "height": height})))

    def warp(day, *extra):
        return run_cli("warp", "--camera", day / "camera.yaml", "--images", day / "images", "--labels", day / "labels",
                       "--label-format", "camvid", "--out", out, *PAPER_STORE, *extra)

    proc = warp(day1)
    assert proc.returncode == 0 and "held" not in proc.stderr and "warning" not in proc.stderr, proc.stderr
    proc = warp(day2, "-q")
    assert proc.returncode == 0 and proc.stdout.strip() == str(out)
    (line,) = proc.stderr.strip().splitlines()
    assert line.startswith(f"warning: {out}: the store held 3 items of camera 'camera' (fx ") and "height 1.21 m" in line
    assert "these 3 frames are of camera 'camera' (fx " in line and "height 1.5 m" in line
    proc = warp(day1)  # frames of its own camera again: no warning, and the summary says what it held
    assert proc.returncode == 0 and "warning" not in proc.stderr and "0 built, 3 up to date" in proc.stderr
    assert "the store held 6 items before" in proc.stderr, proc.stderr


def test_backproject_cli_inverts_the_warp(dataset, tmp_path):
    _, images, labels = dataset
    out = tmp_path / "store"
    assert _warp(images, labels, out, "--scale", "0.25").returncode == 0
    masks = tmp_path / "masks"
    masks.mkdir()
    recs = _records(out)
    for r in recs:  # a virtual-domain 'prediction': the stored label as 0/255
        lab = cv2.imread(str(out / r["label"]), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(masks / f"{r['id']}.png"), np.where(lab == 1, 255, 0).astype(np.uint8))
    proc = run_cli("backproject", out, masks, "--out", tmp_path / "back")
    assert proc.returncode == 0, proc.stderr
    for r in recs:
        back = cv2.imread(str(tmp_path / "back" / f"{r['id']}.png"), cv2.IMREAD_UNCHANGED)
        src = cv2.imread(r["label_source"], cv2.IMREAD_UNCHANGED)
        assert back.shape == src.shape == (360, 480)
        sure = src != 11  # the bonnet was ignore, predicted as 0 here
        agree = ((back == 255) == (src == 3))[sure].mean()
        assert agree > 0.99, agree


def test_every_command_has_help_with_an_example():
    commands = [[], ["cameras"], ["camera"], ["camera", "show"], ["camera", "design"], ["warp"], ["store"],
                ["store", "show"], ["backproject"], ["figure"], ["figure", "warp"]]
    top = run_cli("--help")
    assert top.returncode == 0
    for cmd in commands:
        proc = run_cli(*cmd, "--help")
        assert proc.returncode == 0, cmd
        if cmd and cmd[0] not in ("camera", "store", "figure") or len(cmd) == 2:
            assert "Example" in proc.stdout, cmd


def test_group_help_names_every_command_of_the_group():
    """`vcprep camera --help` (and the store group's) says what the group holds: each of its
    commands is named in the group's one-line description."""
    import typer.main

    from vcprep.cli import app

    root = typer.main.get_command(app)
    for group in ("camera", "store"):
        grp = root.commands[group]
        proc = run_cli(group, "--help")
        assert proc.returncode == 0 and grp.help in " ".join(proc.stdout.split())
        for cmd in grp.commands:
            assert cmd in grp.help, (group, cmd, grp.help)


def test_cameras_and_camera_show(tmp_path):
    proc = run_cli("cameras", "--json")
    rows = [json.loads(x) for x in proc.stdout.splitlines()]
    assert {r["name"] for r in rows} == set(PRESETS)
    v = next(r for r in rows if r["name"] == "virtual")
    assert v["fov_deg"] == pytest.approx([101.1, 63.5], abs=0.1)
    proc = run_cli("camera", "show", EXAMPLES / "kitti" / "calib" / "um_000000.txt", "--json")
    assert json.loads(proc.stdout)["height"] == pytest.approx(1.597, abs=1e-3)


def test_camera_design_reproduces_paper_virtual_camera(tmp_path):
    out = tmp_path / "virtual.yaml"
    proc = run_cli("camera", "design", "camvid", "cityscapes", "kitti", "qian", "toronto2020", "-o", out)
    assert proc.returncode == 0, proc.stderr
    from vcprep.camera import read_camera_yaml
    v = read_camera_yaml(out)
    assert v.height == pytest.approx(1.38, abs=0.005) and v.fx == v.fy == 2262
    assert v.size[0] == pytest.approx(5500, rel=0.03) and v.size[1] == pytest.approx(2800, rel=0.06)
    assert v.cx == (v.size[0] - 1) / 2 and v.tilt == 0


def test_demo_examples_warp(tmp_path):
    out = tmp_path / "s"
    proc = run_cli("warp", "--camera", EXAMPLES / "kitti" / "calib" / "um_000000.txt", "--images",
                   EXAMPLES / "kitti" / "image_2", "--labels", EXAMPLES / "kitti" / "gt_image_2", "--label-format",
                   "kitti", "--out", out)
    assert proc.returncode == 0, proc.stderr
    rec = _records(out)[0]
    lab = cv2.imread(str(out / rec["label"]), cv2.IMREAD_UNCHANGED)
    assert (lab == 1).sum() > 500 and rec["size"] == [1242, 375]
    proc = run_cli("figure", "warp", out, "-o", tmp_path / "fig.png")
    assert proc.returncode == 0 and cv2.imread(str(tmp_path / "fig.png")) is not None


# ---------------------------------------------------------------- bad inputs
def _bad_png(kind):
    def make(images, labels, tmp):
        target = images / "seq_0001.png"
        data = target.read_bytes()
        if kind == "truncated":
            target.write_bytes(data[: len(data) // 2])
        elif kind == "corrupt":
            target.write_bytes(data[:40] + b"\x00garbage" * 50 + data[-12:])
        elif kind == "empty":
            target.write_bytes(b"")
        elif kind == "huge":
            # a 40000x40000 PNG header: refused without allocating it
            import struct, zlib
            ihdr = struct.pack(">IIBBBBB", 40000, 40000, 8, 2, 0, 0, 0)
            chunk = lambda t, d: struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))
            target.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b""))
        return target
    return make


def _wrong_size(images, labels, tmp):
    target = images / "seq_0002.png"
    cv2.imwrite(str(target), np.zeros((300, 480, 3), np.uint8))
    return target


def _label_out_of_range(images, labels, tmp):
    target = labels / "seq_0002.png"
    lab = cv2.imread(str(target), cv2.IMREAD_UNCHANGED)
    lab[5, 5] = 40
    cv2.imwrite(str(target), lab)
    return target


def _truncated_jpeg(images, labels, tmp):
    target = images / "seq_0001.png"
    jpg = images / "seq_0001.jpg"
    data = cv2.imencode(".jpg", cv2.imread(str(target)))[1].tobytes()
    target.unlink()
    jpg.write_bytes(data[: len(data) * 2 // 3])
    return jpg


def _four_channel_label(images, labels, tmp):
    target = labels / "seq_0001.png"
    cv2.imwrite(str(target), np.full((360, 480, 4), 3, np.uint8))
    return target


def _duplicate_id(images, labels, tmp):
    dup = images / "seq_0001.jpg"
    dup.write_bytes(cv2.imencode(".jpg", cv2.imread(str(images / "seq_0001.png")))[1].tobytes())
    return images / "seq_0001.png"  # named in the error, with its twin


def _colour_label_for_ids(images, labels, tmp):
    target = labels / "seq_0002.png"
    cv2.imwrite(str(target), np.dstack([np.zeros((360, 480), np.uint8), np.full((360, 480), 3, np.uint8),
                                        np.zeros((360, 480), np.uint8)]))
    return target


@pytest.mark.parametrize("make, needle", [
    (_truncated_jpeg, "truncated"),
    (_four_channel_label, "4 channels"),
    (_duplicate_id, "duplicate image id"),
    (_colour_label_for_ids, "channels"),
    (_bad_png("truncated"), "truncated"),
    (_bad_png("corrupt"), "decode"),
    (_bad_png("empty"), "empty"),
    (_bad_png("huge"), "40000x40000"),
    (_wrong_size, "not a uniform rescale"),
    (_label_out_of_range, "label value 40"),
])
def test_bad_input_files(dataset, tmp_path, make, needle):
    _, images, labels = dataset
    imgs, labs = tmp_path / "images", tmp_path / "labels"
    shutil.copytree(images, imgs)
    shutil.copytree(labels, labs)
    bad = make(imgs, labs, tmp_path)
    out = tmp_path / "store"
    proc = _warp(imgs, labs, out)
    assert_one_error_line(proc, str(bad), needle)
    if not out.exists():
        return  # refused before anything was written
    # nothing half-written: no temp files; the bad item has no record and no files
    leftovers = [p for p in out.rglob("*") if p.name.startswith(".") or p.suffix == ".tmp"]
    assert not leftovers
    ids = [r["id"] for r in _records(out)]
    assert bad.stem not in ids
    for sub in ("images", "labels"):
        assert not (out / sub / f"{bad.stem}.png").exists()
    assert all((out / "images" / f"{i}.png").exists() for i in ids)
    # valid/ holds only the shared masks the records use
    assert {p.name for p in (out / "valid").glob("*.png")} <= {r["valid"].split("/")[-1] for r in _records(out)}


@pytest.mark.parametrize("args, needle", [
    (["--camera", "nosuchcam"], "not a camera preset"),
    (["--images", "/nonexistent/dir"], "image folder not found"),
    (["--label-format", "pascal"], "unknown label format"),
])
def test_bad_arguments(dataset, tmp_path, args, needle):
    _, images, labels = dataset
    base = {"--camera": "camvid", "--images": str(images), "--labels": str(labels), "--label-format": "camvid",
            "--out": str(tmp_path / "s")}
    base.update(dict(zip(args[::2], args[1::2])))
    proc = run_cli("warp", *[x for kv in base.items() for x in kv])
    assert_one_error_line(proc, needle)


def test_negative_focal_yaml_via_cli(dataset, tmp_path):
    _, images, labels = dataset
    cam = tmp_path / "neg.yaml"
    cam.write_text(camera_to_yaml(PRESETS["camvid"]).replace("fx: 862", "fx: -862"))
    proc = run_cli("warp", "--camera", cam, "--images", images, "--out", tmp_path / "s")
    assert_one_error_line(proc, str(cam), "'fx'")
    assert not (tmp_path / "s").exists()


def test_output_is_a_file(dataset, tmp_path):
    _, images, labels = dataset
    f = tmp_path / "file"
    f.write_text("x")
    assert_one_error_line(_warp(images, labels, f), str(f), "not a directory")


def test_debug_shows_traceback(dataset, tmp_path):
    _, images, labels = dataset
    proc = run_cli("warp", "--camera", "nosuch", "--images", images, "--out", tmp_path / "s", "--debug")
    assert proc.returncode == 1 and "Traceback" in proc.stderr


def test_geometry_figures(tmp_path):
    for cmd in (["figure", "footprints", "camvid", "kitti", "-o", tmp_path / "fp.png"],
                ["figure", "fov", "camvid", "kitti", "--virtual", "virtual", "-o", tmp_path / "fov.png"]):
        proc = run_cli(*cmd)
        assert proc.returncode == 0, proc.stderr
        img = cv2.imread(str(cmd[-1]))
        assert img is not None and img.std() > 10 and "Example" in run_cli(*cmd[:2], "--help").stdout
    assert_one_error_line(run_cli("figure", "fov", "nosuchcam", "-o", tmp_path / "x.png"), "nosuchcam")


def test_camera_design_above_is_an_exact_crop_that_keeps_the_road(tmp_path):
    """--above only moves cy and shortens the image: H differs from the uncropped design's by a
    vertical translation, and every road pixel of every camera, at poses in the design range,
    that lands inside the uncropped design lands inside the cropped one too (rendered roads:
    the exact road mask is known), while a large share of the uncropped image is cut."""
    from vcprep.camera import PRESETS, read_camera_yaml
    from vcprep.warp import apply_homography, virt_H_src
    from vcprep.synthetic import render_road

    names = ["camvid", "kitti", "toronto2020"]
    full, crop = tmp_path / "full.yaml", tmp_path / "crop.yaml"
    for out, extra in ((full, []), (crop, ["--above", "6"])):
        proc = run_cli("camera", "design", *names, "--pan-range", "8", "--tilt-range", "4", "-o", out, *extra)
        assert proc.returncode == 0, proc.stderr
    vf, vc = read_camera_yaml(full), read_camera_yaml(crop)
    assert (vf.fx, vf.cx, vf.size[0], vf.height) == (vc.fx, vc.cx, vc.size[0], vc.height)
    assert vc.size[1] < 0.8 * vf.size[1]
    f = vc.fx
    assert vc.cy + 0.5 == pytest.approx(f * (np.tan(np.radians(6)) + np.tan(np.radians(4))), rel=1e-9)
    T = np.array([[1, 0, 0], [0, 1, vc.cy - vf.cy], [0, 0, 1.0]])
    for name in names:
        cam = PRESETS[name].resized(0.1)
        for pan, tilt in ((0, 0), (8, 4), (-8, -4), (8, -4)):
            Hf = virt_H_src(cam, vf, pan=cam.pan + pan, tilt=cam.tilt + tilt)
            Hc = virt_H_src(cam, vc, pan=cam.pan + pan, tilt=cam.tilt + tilt)
            M = T @ Hf
            assert np.allclose(Hc / Hc[2, 2], M / M[2, 2], atol=1e-9)
            _, lab = render_road(cam, pan=cam.pan + pan, tilt=cam.tilt + tilt, supersample=1)
            v, u = np.nonzero(lab == 1)
            pts = np.stack([u, v], axis=1).astype(float)
            pf, pc = apply_homography(Hf, pts), apply_homography(Hc, pts)
            inside_f = (pf[:, 1] > -0.5) & (pf[:, 1] < vf.size[1] - 0.5)
            inside_c = (pc[:, 1] > -0.5) & (pc[:, 1] < vc.size[1] - 0.5)
            assert inside_f.sum() > 100 and (inside_c | ~inside_f).all()
