"""Road vanishing points: detector accuracy on exact synthetic renders, the reliability rule,
temporal smoothing, the VP CSV reader, within-camera warping (VP -> virtual principal point) and
the `vcprep vp` / `vcprep figure vp` / `vcprep warp --within` commands."""
from __future__ import annotations

import json
import math

import cv2
import numpy as np
import pytest

from vcprep.camera import PRESETS
from vcprep.errors import InputError
from vcprep.warp import apply_homography, pose_from_vp, virtual_at_scale, vp_from_pose
from vcprep.synthetic import RoadScene, render_road
from vcprep.vp import (VPConfig, VPResult, apply_reliability, detect_segments, estimate_vp,
                                    read_vp_csv, refine_segments, score_vps, sequence_key, smooth_sequences,
                                    write_vp_csv)

from conftest import EXAMPLES, run_here, assert_one_error_line, run_cli



RNG_SEED = 7


def _cluttered_render(cam, pan, tilt, rng, n_clutter=6, noise=5.0):
    scene = RoadScene(offset=float(rng.uniform(-2, 2)), width=float(rng.uniform(6, 10)),
                      texture_seed=int(rng.integers(0, 100)))
    img, _ = render_road(cam, scene, pan=pan, tilt=tilt, supersample=1)
    img = img.astype(np.float64) + rng.normal(0, noise, img.shape)
    W, H = cam.size
    for _ in range(n_clutter):  # short random clutter segments (signs, poles, shadows)
        p = rng.uniform([0, 0], [W, H])
        a = rng.uniform(0, math.pi)
        q = p + rng.uniform(20, 80) * np.array([math.cos(a), math.sin(a)])
        cv2.line(img, tuple(int(v) for v in p), tuple(int(v) for v in q), tuple(float(v) for v in rng.uniform(0, 255, 3)), 2)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


@pytest.fixture(scope="module")
def renders(camvid_half):
    """(image, pan, tilt) at random pan +/-20, tilt +/-15 with clutter and noise."""
    rng = np.random.default_rng(RNG_SEED)
    out = []
    for _ in range(8):
        pan, tilt = float(rng.uniform(-20, 20)), float(rng.uniform(-15, 15))
        out.append((_cluttered_render(camvid_half, pan, tilt, rng), pan, tilt))
    return out


# ---------------------------------------------------------------------------------- segments

def _edge_image(angle_deg, point=(240.3, 180.7), size=(480, 360), ss=8):
    """Anti-aliased straight step edge through ``point`` (pixel-centre coordinates) at
    ``angle_deg`` to the horizontal; returns (uint8 image, unit normal, point)."""
    t = math.radians(angle_deg)
    n = np.array([-math.sin(t), math.cos(t)])
    w, h = size
    offs = (np.arange(ss) + 0.5) / ss - 0.5
    u = (np.arange(w)[:, None] + offs).ravel()
    v = (np.arange(h)[:, None] + offs).ravel()
    side = (u[None, :] - point[0]) * n[0] + (v[:, None] - point[1]) * n[1]
    img = np.where(side > 0, 190.0, 70.0).reshape(h, ss, w, ss).mean(axis=(1, 3))
    return np.clip(np.rint(img), 0, 255).astype(np.uint8), n, np.array(point)


def _offsets(seg, n, p):
    """Signed distances of both endpoints of ``seg`` (4,) from the line through ``p`` with normal ``n``."""
    return [float((seg[0] - p[0]) * n[0] + (seg[1] - p[1]) * n[1]), float((seg[2] - p[0]) * n[0] + (seg[3] - p[1]) * n[1])]


@pytest.mark.parametrize("lsd_scale", [0.5, 0.8, 1.0])
@pytest.mark.parametrize("angle", [30.0, 65.0, 120.0, 160.0])
def test_detect_segments_follows_pixel_centre_rule(lsd_scale, angle):
    """A straight edge at a known sub-pixel position is reported on it at every LSD scale
    (OpenCV's LSD is off by 0.5 / scale - 0.5 px when it subsamples; detect_segments corrects it)."""
    img, n, p = _edge_image(angle)
    seg = detect_segments(img, work_width=480, lsd_scale=lsd_scale)
    longest = seg[np.argmax(np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]))]
    assert _offsets(longest, n, p) == pytest.approx([0.0, 0.0], abs=0.15)


@pytest.mark.parametrize("angle", [25.0, 70.0, 135.0])
def test_refine_segments_moves_a_misplaced_segment_onto_its_edge(angle):
    """Known analytic case: a segment shifted and rotated off its edge by ~1 px is re-fitted onto it;
    a segment with no edge under it is left as it is."""
    img, n, p = _edge_image(angle)
    t = np.array([n[1], -n[0]])
    a, b = p - 80 * t, p + 80 * t
    off = np.r_[a + 1.2 * n, b - 0.8 * n]                     # endpoints 1.2 px and 0.8 px off
    out = refine_segments(img, off[None, :])[0]
    assert _offsets(out, n, p) == pytest.approx([0.0, 0.0], abs=0.15)
    flat = np.full_like(img, 90)
    assert refine_segments(flat, off[None, :])[0] == pytest.approx(off)
    assert refine_segments(img, np.zeros((0, 4))).shape == (0, 4)


# ---------------------------------------------------------------------------------- detector

def test_smoke_result_fields(camvid_half, renders):
    r = estimate_vp(renders[0][0], camvid_half)
    assert isinstance(r, VPResult)
    assert r.status in ("accepted", "rejected")
    assert len(r.vp) == 2 and all(math.isfinite(x) for x in r.vp)
    assert 0.0 <= r.confidence <= 1.0
    assert r.segments.shape[1] == 4 and r.support.shape == (len(r.segments),)
    assert r.n_support == int(r.support.sum())
    assert (r.pan_deg, r.tilt_deg) == pytest.approx(pose_from_vp(camvid_half, r.vp))


def test_vp_error_bound_on_synthetic_renders(camvid_half, renders):
    """Median error below 0.5 % of the width and every image below 3 %."""
    errs = []
    for img, pan, tilt in renders:
        r = estimate_vp(img, camvid_half)
        gt = vp_from_pose(camvid_half, pan, tilt)
        errs.append(math.hypot(r.vp[0] - gt[0], r.vp[1] - gt[1]) / camvid_half.width * 100)
        assert r.status == "accepted", (pan, tilt, r.reason)
    assert np.median(errs) < 0.5, errs
    assert max(errs) < 3.0, errs


def _one_sided_distractor(cam, pan, tilt, dx, dy, n, side, length=90):
    """A road render (exact VP from the pose) plus a fan of ``n`` bright lines aimed at the point
    D = VP + (dx, dy), all lying below D and on ONE side of its vertical (``side`` +1: right),
    like a row of parked cars or a kerb of a side road: a mode that is supported from one side only."""
    img, _ = render_road(cam, RoadScene(width=7.0), pan=pan, tilt=tilt, supersample=2)
    img = img.copy()
    gt = np.array(vp_from_pose(cam, pan, tilt))
    D = gt + [dx, dy]
    for k in range(n):
        a = math.radians(18 + 50 * k / max(1, n - 1))
        d = np.array([side * math.cos(a), math.sin(a)])
        p, q = D + 40 * d, D + (40 + length) * d
        cv2.line(img, tuple(int(round(v)) for v in p), tuple(int(round(v)) for v in q), (255, 255, 255), 2, cv2.LINE_AA)
    return img, gt, D


@pytest.mark.parametrize("dx, dy, n, side", [(-60, 10, 10, -1), (-50, -10, 8, 1)])
def test_two_sided_score_beats_a_one_sided_distractor(camvid_half, dx, dy, n, side):
    """The plain vote (one_sided=1) takes the distractor fan; the two-sided factor takes the road's
    exact VP. The pose prior is switched off to isolate the factor (the distractor lies nearer the
    camera's average pose than the road's VP, so the prior could not help), then on (default)."""
    img, gt, D = _one_sided_distractor(camvid_half, 8.0, 2.0, dx, dy, n, side)
    w = camvid_half.width
    plain = estimate_vp(img, camvid_half, VPConfig(pose_sigma=0.0, one_sided=1.0))
    assert math.dist(plain.vp, D) < 0.02 * w, (plain.vp, D)        # the scene is a real trap
    two = estimate_vp(img, camvid_half, VPConfig(pose_sigma=0.0))
    assert math.dist(two.vp, gt) < 0.005 * w, (two.vp, gt)
    default = estimate_vp(img, camvid_half)
    assert math.dist(default.vp, gt) < 0.005 * w and default.status == "accepted", (default.vp, gt)


def test_score_vps_ranks_the_modes_as_the_detector_does(camvid_half):
    """score_vps is the detector's own score: on the distractor scene the plain vote scores its
    detection on the fan (near D) above the road's exact VP, and the default score the exact VP
    above that point, as each one's estimate_vp picks."""
    img, gt, D = _one_sided_distractor(camvid_half, 8.0, 2.0, -60, 10, 10, -1)
    plain = VPConfig(pose_sigma=0.0, one_sided=1.0)
    on_fan = estimate_vp(img, camvid_half, plain).vp
    assert math.dist(on_fan, D) < 0.02 * camvid_half.width
    s_plain = score_vps(img, camvid_half, [gt, on_fan], plain)
    assert s_plain.shape == (2,) and s_plain[1] > s_plain[0] > 0
    s_default = score_vps(img, camvid_half, [gt, on_fan])
    assert s_default[0] > s_default[1] > 0


@pytest.mark.parametrize("pan, tilt", [(8.0, 2.0), (-12.0, -5.0)])
def test_score_vps_peaks_at_the_detection(camvid_half, pan, tilt):
    """On a clean render the detection scores at least 95 % of the exact VP's score (the detector keeps
    its least-squares refinement when it holds 95 % of the best candidate's score), and points
    3 % of the width around the exact VP clearly less."""
    img, _ = render_road(camvid_half, RoadScene(width=7.0), pan=pan, tilt=tilt, supersample=2)
    gt = np.array(vp_from_pose(camvid_half, pan, tilt))
    det = estimate_vp(img, camvid_half).vp
    ring = [gt + 0.03 * camvid_half.width * np.array([math.cos(a), math.sin(a)]) for a in np.arange(8) * math.pi / 4]
    s = score_vps(img, camvid_half, [det, gt, *ring])
    assert s[1] > 0 and s[0] >= 0.95 * s[1] and np.all(s[2:] < 0.9 * s[1]), s


def test_score_vps_reads_ego_rows_as_the_bottom_crop(camvid_half):
    """A camera with ego_rows scores exactly as the hand-cropped image with the cropped camera;
    an image without usable lines scores 0 everywhere."""
    from dataclasses import replace

    img, _ = render_road(camvid_half, RoadScene(width=7.0), pan=4.0, tilt=1.0, supersample=2)
    img = img.copy()
    cv2.rectangle(img, (0, 330), (479, 359), (200, 200, 200), -1)
    for k in range(6):                                      # a decoy fan on the bonnet rows
        cv2.line(img, (60 + 60 * k, 359), (240, 331), (0, 0, 0), 2)
    cam_ego = replace(camvid_half, ego_rows=30)
    pts = [vp_from_pose(camvid_half, 4.0, 1.0), (240.0, 300.0), (100.0, 150.0)]
    cropped = replace(camvid_half, size=(480, 330), ego_rows=0)
    assert np.array_equal(score_vps(img, cam_ego, pts), score_vps(img[:330], cropped, pts))
    assert not np.array_equal(score_vps(img, cam_ego, pts), score_vps(img, camvid_half, pts))
    assert np.all(score_vps(np.full((360, 480, 3), 128, np.uint8), camvid_half, pts) == 0)


def test_pose_prior_is_a_gaussian_of_the_implied_pose(camvid_half):
    """_scores' prior factor equals exp(-d_pan^2 / 2 s_pan^2 - d_tilt^2 / 2 s_tilt^2), the pose
    taken from pose_from_vp (independent code), s = pose_sigma x the reliability window; checked
    on a camera with a non-zero average pose so that a sign error shows."""
    from dataclasses import replace

    from vcprep.vp.estimate import _scores

    cam = replace(camvid_half, pan=3.0, tilt=-2.0)
    cfg = VPConfig(one_sided=1.0)
    poses = [(3.0, -2.0), (13.0, -2.0), (3.0, 10.0), (-15.0, -12.0)]
    cands = np.array([vp_from_pose(cam, a, b) for a, b in poses])
    mid = np.array([[cam.cx, cam.cy + 100.0]])           # one vertical segment below the centre
    dirs = np.array([[0.0, 1.0]])
    with_prior = _scores(cands, mid, dirs, np.array([10.0]), np.array([1.0]), 1.0, cam, cfg)
    without = _scores(cands, mid, dirs, np.array([10.0]), np.array([1.0]), 1.0, cam, replace(cfg, pose_sigma=0.0))
    assert np.all(without > 0)
    s_pan, s_tilt = cfg.pose_sigma * cfg.pan_range, cfg.pose_sigma * cfg.tilt_range
    for k, vp in enumerate(cands):
        pan, tilt = pose_from_vp(cam, vp)
        expect = math.exp(-0.5 * ((pan - 3.0) / s_pan) ** 2 - 0.5 * ((tilt + 2.0) / s_tilt) ** 2)
        assert with_prior[k] / without[k] == pytest.approx(expect, rel=1e-9), poses[k]


def test_deterministic(camvid_half, renders):
    a = estimate_vp(renders[1][0], camvid_half)
    b = estimate_vp(renders[1][0].copy(), camvid_half)
    assert a.vp == b.vp and a.n_support == b.n_support


def test_rescaled_image_gives_rescaled_vp():
    """Same scene at 960x720 and 480x360: each VP is in its own image's pixels, same pose."""
    big = PRESETS["camvid"]
    small = big.for_image_size((480, 360))
    img, _ = render_road(big, RoadScene(), pan=6.0, tilt=-4.0, supersample=1)
    r = estimate_vp(img, big)
    rs = estimate_vp(cv2.resize(img, small.size, interpolation=cv2.INTER_AREA), small)
    for res in (r, rs):
        assert res.pan_deg == pytest.approx(6.0, abs=1.5) and res.tilt_deg == pytest.approx(-4.0, abs=1.5)


@pytest.mark.parametrize("kind", ["uniform", "noise", "tiny"])
def test_no_usable_lines_is_rejected_not_a_crash(camvid_half, kind):
    if kind == "uniform":
        img, cam = np.full((360, 480, 3), 90, np.uint8), camvid_half
    elif kind == "noise":
        img, cam = np.random.default_rng(0).integers(0, 255, (360, 480), dtype=np.uint8), camvid_half
    else:
        cam = PRESETS["camvid"].for_image_size((8, 6))
        img = np.zeros((6, 8, 3), np.uint8)
    r = estimate_vp(img, cam)
    assert r.status == "rejected" and r.reason
    assert all(math.isfinite(x) for x in (*r.vp, r.pan_deg, r.tilt_deg, r.confidence))
    f = apply_reliability([r], [cam])[0]
    assert f.status == "fallback" and f.vp == pytest.approx(vp_from_pose(cam))


def test_wrong_camera_size_raises(camvid_half):
    with pytest.raises(InputError):
        estimate_vp(np.zeros((100, 100, 3), np.uint8), camvid_half)


# ---------------------------------------------------------------------------------- reliability rule

def _res(cam, vp, n=10, status="accepted"):
    pan, tilt = pose_from_vp(cam, vp)
    return VPResult(vp=vp, confidence=0.5, n_support=n, pan_deg=pan, tilt_deg=tilt, status=status)


def test_reliability_rule_thresholds(camvid_half):
    from vcprep.vp import is_reliable

    cfg = VPConfig()
    assert is_reliable(camvid_half, 19.9, 0, 10, cfg) == ""
    assert "pan" in is_reliable(camvid_half, 20.1, 0, 10, cfg)
    assert "pan" in is_reliable(camvid_half, -20.1, 0, 10, cfg)
    assert is_reliable(camvid_half, 0, 14.9, 10, cfg) == ""
    assert "tilt" in is_reliable(camvid_half, 0, -15.1, 10, cfg)
    assert "support" in is_reliable(camvid_half, 0, 0, cfg.min_support - 1, cfg)
    tilted = camvid_half.with_pose(tilt=10.0)  # relative to the camera's average pose
    assert is_reliable(tilted, 0, 24.0, 10, cfg) == ""


def test_an_out_of_range_detection_is_rejected(camvid_half):
    """A road panned by 30 deg is outside the prior: the detector must not report it accepted."""
    img, _ = render_road(camvid_half, RoadScene(), pan=0.0, tilt=0.0, supersample=1)
    r = estimate_vp(img, camvid_half.with_pose(pan=-30.0 + 0.0))  # camera thinks it looks 30 deg left
    assert r.status == "rejected" or abs(r.pan_deg - (-30.0)) <= 20.0


def test_fallback_is_mean_of_accepted_over_rays(camvid_half):
    big = PRESETS["camvid"]
    a = _res(camvid_half, (250.0, 170.0))
    b = _res(big, vp_from_pose(big, 4.0, -2.0))
    bad = _res(camvid_half, (10.0, 10.0), status="rejected")
    out = apply_reliability([a, b, bad], [camvid_half, big, camvid_half])
    assert [r.status for r in out] == ["accepted", "accepted", "fallback"]
    rays = [((a.vp[0] - camvid_half.cx) / camvid_half.fx, (a.vp[1] - camvid_half.cy) / camvid_half.fy),
            ((b.vp[0] - big.cx) / big.fx, (b.vp[1] - big.cy) / big.fy)]
    m = np.mean(rays, axis=0)
    assert out[2].vp == pytest.approx((camvid_half.cx + camvid_half.fx * m[0], camvid_half.cy + camvid_half.fy * m[1]))
    assert "replaced by the mean of 2 accepted" in out[2].reason


def _two_rigs(cam, n_b_accepted=3):
    """Rig A at tilt 0, rig B looking 5 deg further down (its own mount), pans -2, 0, 2, 4 deg:
    4 accepted VPs of A, ``n_b_accepted`` of B and one rejected frame of B."""
    ids, res = [], []
    for k, pan in enumerate((-2.0, 0.0, 2.0, 4.0)):
        ids.append(f"A_{k:04d}"), res.append(_res(cam, vp_from_pose(cam, pan, 0.0)))
    for k, pan in enumerate((-2.0, 0.0, 2.0, 4.0)[:n_b_accepted]):
        ids.append(f"B_{k:04d}"), res.append(_res(cam, vp_from_pose(cam, pan, -5.0)))
    ids.append("B_0099"), res.append(_res(cam, (10.0, 10.0), n=2, status="rejected"))
    return ids, res


def test_fallback_takes_the_sequence_mean(camvid_half):
    """With ids, a rejected frame takes its own sequence's mean (over rays): rig B's tilt, not the
    run's mix of both rigs; the reason names the sequence. Without ids: the run's mean."""
    ids, res = _two_rigs(camvid_half)
    cams = [camvid_half] * len(res)
    seq = apply_reliability(res, cams, ids)[-1]
    assert seq.status == "fallback" and "of sequence B" in seq.reason and "3 accepted" in seq.reason
    rays = np.array([[(r.vp[0] - camvid_half.cx) / camvid_half.fx, (r.vp[1] - camvid_half.cy) / camvid_half.fy]
                     for r in res[4:7]])
    m = rays.mean(axis=0)
    assert seq.vp == pytest.approx((camvid_half.cx + camvid_half.fx * m[0], camvid_half.cy + camvid_half.fy * m[1]))
    assert seq.tilt_deg == pytest.approx(-5.0, abs=0.02) and seq.pan_deg == pytest.approx(0.0, abs=0.05)
    run = apply_reliability(res, cams)[-1]
    assert "of sequence" not in run.reason and "mean of 7 accepted" in run.reason
    assert run.tilt_deg == pytest.approx(-5.0 * 3 / 7, abs=0.05)  # the mixed mean, 2.9 deg off rig B
    assert apply_reliability(res, cams, ids)[:-1] == res[:-1]      # accepted ones pass through


def test_fallback_with_too_few_in_the_sequence_takes_the_run_mean(camvid_half):
    ids, res = _two_rigs(camvid_half, n_b_accepted=2)
    out = apply_reliability(res, [camvid_half] * len(res), ids)[-1]
    assert "mean of 6 accepted" in out.reason and "sequence" not in out.reason
    with pytest.raises(ValueError):
        apply_reliability(res, [camvid_half] * len(res), ids[:-1])


def test_vp_command_falls_back_to_the_frame_s_own_sequence(tmp_path, camvid_half):
    """`vcprep vp` on a folder mixing two rigs (file names A_..., B_...): the unusable frame of rig
    B gets rig B's pose, estimated from its rendered frames."""
    d = tmp_path / "imgs"
    d.mkdir()
    for rig, tilt in (("A", 0.0), ("B", -5.0)):
        for k, pan in enumerate((-3.0, 0.0, 3.0)):
            img, _ = render_road(camvid_half, RoadScene(texture_seed=k), pan=pan, tilt=tilt, supersample=1)
            cv2.imwrite(str(d / f"{rig}_{k:04d}.png"), img)
    cv2.imwrite(str(d / "B_0099.png"), np.full((360, 480, 3), 90, np.uint8))
    proc = run_here("vp", "--camera", "camvid", d, "--json", "-q")
    assert proc.returncode == 0, proc.stderr
    objs = {json.loads(line)["image"].rsplit("/", 1)[-1]: json.loads(line) for line in proc.stdout.splitlines()}
    fb = objs["B_0099.png"]
    assert fb["status"] == "fallback" and "of sequence B" in fb["reason"]
    assert fb["tilt_deg"] == pytest.approx(-5.0, abs=0.3) and fb["pan_deg"] == pytest.approx(0.0, abs=0.5)


def test_sequence_key_and_smoothing(camvid_half):
    assert sequence_key("0016E5_07959") == "0016E5"
    assert sequence_key("frame") == "frame"
    ids = [f"seqA_{i:03d}" for i in range(5)] + ["seqB_000"]
    vps = [(240.0, 180.0), (241.0, 181.0), (300.0, 100.0), (242.0, 182.0), (243.0, 183.0), (100.0, 200.0)]
    res = [_res(camvid_half, v) for v in vps]
    out = smooth_sequences(ids, res, [camvid_half] * len(ids), window=2)
    assert out[2].vp == pytest.approx((242.0, 181.0))  # the outlier frame takes the median of frames 0..4
    assert out[5].vp == pytest.approx(vps[5])           # another sequence is not mixed in
    assert smooth_sequences(ids, res, [camvid_half] * len(ids), window=0)[2].vp == vps[2]


def test_a_rule_groups_the_same_frames_the_same_way_whatever_their_ids():
    """VPRule.frame_ids: sequences by file name (a study's CamVid ids, predict's stems, a suffixed
    Cityscapes stem: one key), or by folder (IDD's drives, whose file names repeat)."""
    from vcprep.vp import VPRule

    name = VPRule().frame_ids(["a/0016E5_07959.png", "b/aachen_000000_000019_leftImg8bit.png", "c/frame.png"])
    assert [sequence_key(i) for i in name] == ["0016E5", "aachen", "frame"]
    folder = VPRule(sequences="folder").frame_ids(["idd/0/024541_image.jpg", "idd/0/024703_image.jpg",
                                                   "idd/1/024541_image.jpg", "x/a_b/f.png"])
    assert [sequence_key(i) for i in folder] == ["0", "0", "1", "a-b"] and len(set(folder)) == 4
    assert VPRule.from_dict(VPRule(10, 5, 2, "folder").to_dict()) == VPRule(10, 5, 2, "folder")
    assert VPRule.from_dict({"pan_range": 10, "tilt_range": 5}) == VPRule(10, 5)  # (sequences: by name)
    with pytest.raises(InputError, match="unknown VP sequence rule"):
        VPRule(sequences="drive")


# ---------------------------------------------------------------------------------- CSV

def test_csv_round_trip(tmp_path, camvid_half):
    res = [_res(camvid_half, (240.5, 180.25)), _res(camvid_half, (200.0, 150.0))]
    p = tmp_path / "vps.csv"
    write_vp_csv(p, ["a", "b"], res)
    assert read_vp_csv(p) == {"a": (240.5, 180.25), "b": (200.0, 150.0)}


def test_csv_without_header_and_with_comments(tmp_path):
    p = tmp_path / "vps.csv"
    p.write_text("# hand-annotated\nx_1, 10, 20\n\nx_2,11.5,21\n")
    assert read_vp_csv(p) == {"x_1": (10.0, 20.0), "x_2": (11.5, 21.0)}


@pytest.mark.parametrize("text, needle", [
    ("id,u,v\na,1,2\na,3,4\n", "line 3: duplicate id 'a' (first on line 2)"),
    ("id,u,v\na,1\n", "line 2"),
    ("id,u,v\na,1,\n", "line 2"),
    ("id,u,v\na,one,2\n", "line 2 ('a')"),
    ("id,u,v\na,nan,2\n", "finite"),
    ("id,u,v\n", "no rows"),
    ("", "no rows"),
])
def test_csv_bad_rows_name_the_line(tmp_path, text, needle):
    p = tmp_path / "vps.csv"
    p.write_text(text)
    with pytest.raises(InputError) as e:
        read_vp_csv(p)
    assert needle in str(e.value) and str(p) in str(e.value)


def test_csv_missing_file(tmp_path):
    with pytest.raises(InputError, match="not found"):
        read_vp_csv(tmp_path / "nope.csv")


# ---------------------------------------------------------------------------------- CLI

@pytest.fixture(scope="module")
def posed_dataset(tmp_path_factory, camvid_half):
    """Three synthetic frames of one sequence at different poses + their exact VPs as a CSV."""
    root = tmp_path_factory.mktemp("vpds")
    img_dir = root / "images"
    img_dir.mkdir()
    poses = [(8.0, -5.0), (-12.0, 6.0), (3.0, 11.0)]
    rows = ["id,u,v"]
    for i, (pan, tilt) in enumerate(poses):
        img, _ = render_road(camvid_half, RoadScene(texture_seed=i), pan=pan, tilt=tilt, supersample=1)
        cv2.imwrite(str(img_dir / f"seq_{i:04d}.png"), img)
        u, v = vp_from_pose(camvid_half, pan, tilt)
        rows.append(f"seq_{i:04d},{u!r},{v!r}")
    (root / "vps.csv").write_text("\n".join(rows) + "\n")
    return root, img_dir, poses


def _records(store):
    proc = run_here("store", "show", store, "--json")
    assert proc.returncode == 0, proc.stderr
    return [json.loads(line) for line in proc.stdout.splitlines()]


@pytest.mark.parametrize("within", ["file", "estimate"])
def test_warp_within_maps_each_vp_to_virtual_principal_point(posed_dataset, tmp_path, within):
    root, img_dir, poses = posed_dataset
    arg = str(root / "vps.csv") if within == "file" else "estimate"
    out = tmp_path / "store"
    proc = run_cli("warp", "--camera", "camvid", "--images", img_dir, "--out", out, "--within", arg,
                   "--complete", "none", "-q", "--virtual", "virtual", "--scale", "0.125")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(out)
    vs = virtual_at_scale(PRESETS["virtual"], 0.125)
    recs = _records(out)
    assert len(recs) == 3
    for rec, (pan, tilt) in zip(sorted(recs, key=lambda r: r["id"]), poses):
        assert rec["vp_status"] == ("given" if within == "file" else "accepted")
        H = np.array(rec["H"]).reshape(3, 3)
        assert apply_homography(H, [rec["vp"]])[0] == pytest.approx((vs.cx, vs.cy), abs=1e-6)
        assert (rec["pan_deg"], rec["tilt_deg"]) == pytest.approx(pose_from_vp(PRESETS["camvid"].for_image_size((480, 360)), rec["vp"]))
        tol = 1e-6 if within == "file" else 0.5
        assert rec["pan_deg"] == pytest.approx(pan, abs=tol) and rec["tilt_deg"] == pytest.approx(tilt, abs=tol)


def test_vp_command_json_and_csv(posed_dataset, tmp_path):
    root, img_dir, poses = posed_dataset
    files = sorted(img_dir.glob("*.png"))
    proc = run_here("vp", "--camera", "camvid", *files, "--json", "-q")
    assert proc.returncode == 0, proc.stderr
    objs = [json.loads(line) for line in proc.stdout.splitlines()]
    assert [o["image"] for o in objs] == [str(f) for f in files]
    for o in objs:
        assert {"image", "vp", "confidence", "n_support", "pan_deg", "tilt_deg", "status"} <= set(o)
        assert o["status"] == "accepted"
    out = tmp_path / "vps.csv"
    proc = run_here("vp", "--camera", "camvid", img_dir, "-o", out)
    assert proc.returncode == 0 and proc.stdout.strip() == str(out)
    assert "3 accepted" in proc.stderr
    assert set(read_vp_csv(out)) == {f.stem for f in files}


def test_vp_command_uniform_image_falls_back(tmp_path):
    p = tmp_path / "grey_0001.png"
    cv2.imwrite(str(p), np.full((360, 480, 3), 128, np.uint8))
    proc = run_here("vp", "--camera", "camvid", p, EXAMPLES / "camvid" / "images" / "0001TP_007170.png", "--json", "-q")
    assert proc.returncode == 0, proc.stderr
    grey, real = [json.loads(line) for line in proc.stdout.splitlines()]
    assert grey["status"] == "fallback" and real["status"] == "accepted"
    assert grey["vp"] == pytest.approx(real["vp"], abs=1e-2)  # mean of the one accepted VP


def test_figure_vp(tmp_path):
    out = tmp_path / "vp.png"
    proc = run_here("figure", "vp", EXAMPLES / "camvid" / "images" / "0016E5_05280.png", "--camera", "camvid", "-o", out)
    assert proc.returncode == 0, proc.stderr
    img = cv2.imread(str(out))
    assert img is not None and img.shape[1] == 480 and img.shape[0] > 360


@pytest.mark.parametrize("case", ["missing_row", "duplicate", "unparsable", "no_file", "smooth_without_estimate"])
def test_warp_within_bad_inputs_one_error_line(posed_dataset, tmp_path, case):
    root, img_dir, _ = posed_dataset
    good = (root / "vps.csv").read_text().splitlines()
    csv_path = tmp_path / "bad.csv"
    extra = []
    if case == "missing_row":
        csv_path.write_text("\n".join(good[:-1]) + "\n")
        needles = ("no VP row for image id 'seq_0002'", str(csv_path))
    elif case == "duplicate":
        csv_path.write_text("\n".join(good + [good[1]]) + "\n")
        needles = ("duplicate id 'seq_0000'", "line 5")
    elif case == "unparsable":
        csv_path.write_text("\n".join(good[:2] + ["seq_0001,abc,3"] + good[3:]) + "\n")
        needles = ("line 3 ('seq_0001')",)
    elif case == "no_file":
        csv_path = tmp_path / "absent.csv"
        needles = ("not found",)
    else:
        extra, needles = ["--vp-smooth", "2"], ("--vp-smooth",)
    proc = run_cli("warp", "--camera", "camvid", "--images", img_dir, "--out", tmp_path / "st", "--within", csv_path,
                   "-q", *extra)
    assert_one_error_line(proc, *needles)
    assert not (tmp_path / "st").exists()


def test_vp_command_bad_inputs(tmp_path):
    proc = run_here("vp", "--camera", "camvid", tmp_path / "nope.png")
    assert_one_error_line(proc, "nope.png", "not found")
    bad = tmp_path / "odd.png"
    cv2.imwrite(str(bad), np.zeros((100, 100, 3), np.uint8))
    proc = run_here("vp", "--camera", "camvid", bad)
    assert_one_error_line(proc, "odd.png", "not a uniform rescale")
    proc = run_here("figure", "vp", bad, "--camera", "camvid", "-o", tmp_path / "missing" / "f.png")
    assert_one_error_line(proc)


@pytest.mark.parametrize("cmd", [["vp"], ["figure", "vp"], ["warp"]])
def test_help_has_example(cmd):
    proc = run_cli(*cmd, "--help")
    assert proc.returncode == 0
    assert "Example:" in proc.stdout


# -- the detector's VPs kept on disk (vcprep.vp.cache; issue 60: an interrupted warp resumes) -------------

def test_a_vp_cache_gives_back_exactly_what_the_detector_found_and_is_read_not_recomputed(camvid_half, tmp_path):
    """estimate_files through a cache equals it without one, field for field; a new cache over the
    same file gives the same results without the detector (a tampered line comes back as written),
    and a torn last line is skipped."""
    from conftest import write_synthetic_dataset
    from vcprep.vp import VPCache, estimate_files

    images, _ = write_synthetic_dataset(tmp_path / "d", camvid_half, n=4, poses=[(0, 0), (2, -1), (-3, 1), (1, 2)])
    files = sorted(images.glob("*.png"))
    fields = lambda r: (r.vp, r.confidence, r.n_support, r.pan_deg, r.tilt_deg, r.status, r.reason, r.detected)  # noqa
    plain = estimate_files(files, camvid_half)
    path = tmp_path / "vps.jsonl"
    first = estimate_files(files, camvid_half, cache=VPCache(path))
    assert [fields(r) for r in first] == [fields(r) for r in plain]
    assert len(path.read_text().splitlines()) == 4 and len(VPCache(path)) == 4
    # tamper with frame 2's line: a cache that is read gives the tampered VP back
    rows = [json.loads(line) for line in path.read_text().splitlines()]
    rows[2]["result"]["detected"] = [1.5, 2.5]
    path.write_text("".join(json.dumps(r) + "\n" for r in rows) + '{"key": "torn')
    again = estimate_files(files, camvid_half, cache=VPCache(path))
    assert again[2].detected == (1.5, 2.5)
    assert [fields(r) for k, r in enumerate(again) if k != 2] == [fields(r) for k, r in enumerate(plain) if k != 2]
    other = estimate_files(files, camvid_half, VPConfig(min_support=VPConfig().min_support + 1), cache=VPCache(path))
    assert len(VPCache(path)) == 8 and other[2].detected != (1.5, 2.5)  # other settings: other keys;
    assert path.read_text().count("\n") == 9  # (the torn line kept, closed before the first new one)


def test_warp_stopped_while_finding_vps_says_so_and_the_rerun_finds_only_the_rest(camvid_half, tmp_path):
    """Ctrl-C while `vcprep warp` finds the road VPs: exit 130, the one line says that nothing is
    warped yet and where the VPs found so far are kept (no 'finished items are saved'); the rerun
    takes those from the cache (the file only grows by the others) and writes the store an
    uninterrupted warp writes."""
    import os
    import signal
    import subprocess
    import time

    from conftest import BIN, default_sigint, write_synthetic_dataset

    n = 40
    images, labels = write_synthetic_dataset(tmp_path / "d", camvid_half, n=n,
                                             poses=[((k % 7) - 3.0, (k % 5) - 2.0) for k in range(n)])
    args = ["warp", "--camera", "camvid", "--images", images, "--labels", labels, "--label-format", "camvid"]
    ref = run_cli(*args, "--out", tmp_path / "ref", "-q")
    assert ref.returncode == 0, ref.stderr
    out = tmp_path / "store"
    cache = out / ".vp-cache.jsonl"
    proc = subprocess.Popen([str(BIN / "vcprep"), *map(str, args), "--out", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True, preexec_fn=default_sigint)
    t = time.monotonic() + 60
    while proc.poll() is None and time.monotonic() < t and not (cache.exists() and cache.read_text().count("\n") >= 2):
        time.sleep(0.002)
    os.killpg(proc.pid, signal.SIGINT)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    kept = cache.read_text().count("\n")
    assert 2 <= kept < n, "the stop should land while the VPs are found"
    assert "Traceback" not in stderr and "finished items are saved" not in stderr
    assert f"while finding road VPs, before warping; the {kept} found so far are kept in {cache}" in stderr
    assert not (out / "manifest.jsonl").exists()
    again = run_cli(*args, "--out", out, "-q")
    assert again.returncode == 0, again.stderr
    assert cache.read_text().count("\n") == n  # only the others were found
    files = lambda root: {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))  # noqa: E731
                          if p.is_file() and p.name != ".vp-cache.jsonl"}
    assert files(out) == files(tmp_path / "ref")
