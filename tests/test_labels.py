"""Labels that make no sense under their format (vcprep.labels.RoadShare; issue 52 item 6): over a set,
road that covers none or nearly all of the labelled pixels, or lies mostly in the frames' upper half,
is a warning in ``vcprep warp`` and ``vctrain eval``. Oracles: labels rendered with known geometry
(vcprep.synthetic: road below the horizon), and the shipped CamVid labels (3 road, 1 building)."""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from conftest import run_cli
from vcprep.camera import PRESETS
from vcprep.labels import decode_label, get_label_format
from vcprep.synthetic import RoadScene, render_road

ROOT = Path(__file__).resolve().parent.parent
CAMVID_IMAGES, CAMVID_LABELS = ROOT / "examples/camvid/images", ROOT / "examples/camvid/labels"


@pytest.fixture(scope="module")
def rendered():
    cam = PRESETS["camvid"].for_image_size((240, 180))
    return [render_road(cam, RoadScene(offset=0.5 * i - 1, texture_seed=i), pan=i - 2.0, supersample=1)[1]
            for i in range(5)]


def _share(labels, spec):
    from vcprep.labels import RoadShare

    s = RoadShare()
    for lab in labels:
        s.add(decode_label(lab, get_label_format(spec)))
    return s


@pytest.mark.parametrize("spec,needle", [
    ("values:road=1", None),                               # the format the labels were rendered with
    ("values:road=2", "no labelled pixel of 5 frames reads as road"),   # an id the labels never hold
    ("values:road=0,1", "road covers 100.00% of the labelled pixels"),  # every class read as road
    ("values:road=0", "lie in the frames' upper half"),    # not road (the sky above the horizon) read as road
])
def test_road_share_of_rendered_labels(rendered, spec, needle):
    share = _share(rendered, spec)
    if needle is None:
        assert share.problem() is None and share.warning(get_label_format(spec), "labels") is None
        assert share.upper == 0 and 0.05 < share.road / share.labelled < 0.6  # the oracle: road below the horizon
        return
    assert needle in share.problem()
    line = share.warning(get_label_format(spec), "labels/")
    assert line.startswith("warning: labels/: ") and f"'{spec}'" in line and "--label-format" in line
    assert "\n" not in line


def test_ignore_does_not_count_and_nothing_labelled_says_nothing(rendered):
    lab = rendered[0].copy()
    lab[lab == 0] = 255                                     # everything but road ignored: road is all there is
    assert "100.00%" in _share([lab], "values:road=1;ignore=255").problem()
    assert _share([np.full((4, 4), 255, np.uint8)], "values:road=1;ignore=255").problem() is None


def _warnings(stderr: str) -> list[str]:
    return [ln for ln in stderr.splitlines() if ln.startswith("warning: ")]


def test_warp_warns_on_a_format_that_reads_buildings_as_road(tmp_path):
    """CamVid labels (3 road, 1 building) read with values:road=1: buildings become road, in the upper
    half of the frames; said even under --quiet, once; the right format says nothing."""
    args = ["warp", "--camera", "camvid", "--images", CAMVID_IMAGES, "--labels", CAMVID_LABELS, "--quiet"]
    proc = run_cli(*args, "--label-format", "values:road=1;ignore=11", "--out", tmp_path / "wrong")
    assert proc.returncode == 0, proc.stderr
    warned = _warnings(proc.stderr)
    assert len(warned) == 1 and proc.stderr.strip() == warned[0], proc.stderr
    assert str(CAMVID_LABELS) in warned[0] and "'values:road=1;ignore=11'" in warned[0]
    assert "upper half" in warned[0] and "--label-format" in warned[0]
    proc = run_cli(*args, "--label-format", "camvid", "--out", tmp_path / "right")
    assert proc.returncode == 0 and proc.stderr.strip() == "", proc.stderr


def test_eval_warns_on_a_format_that_finds_no_road(tmp_path):
    """Predictions that are the CamVid labels' own road (IoU 1 under the right format) scored with
    formats that read no road, or buildings as road: IoU 0 and a warning naming the format."""
    preds = tmp_path / "preds"
    preds.mkdir()
    for p in sorted(CAMVID_LABELS.glob("*.png")):
        lab = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(preds / f"{p.stem}_mask.png"), np.where(lab == 3, 255, 0).astype(np.uint8))
    proc = run_cli("eval", preds, "--labels", CAMVID_LABELS, "--label-format", "camvid", "--json", "--quiet",
                   prog="vctrain")
    assert proc.returncode == 0 and '"iou": 1.0' in proc.stdout and proc.stderr.strip() == "", proc.stderr
    for spec, needle in (("values:road=12;ignore=11", "no labelled pixel of 3 frames reads as road"),
                         ("values:road=1;ignore=11", "upper half")):
        proc = run_cli("eval", preds, "--labels", CAMVID_LABELS, "--label-format", spec, "--json", "--quiet",
                       prog="vctrain")
        assert proc.returncode == 0 and '"iou": 0.0' in proc.stdout, proc.stdout
        warned = _warnings(proc.stderr)
        assert len(warned) == 1 and needle in warned[0] and f"'{spec}'" in warned[0], proc.stderr


# -- KITTI road labels read as the devkit reads them (issue 70) ------------------------------------------------
KITTI = ROOT / "examples/kitti"


def _kitti_with_strays(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The shipped KITTI label (BGR) with stray colours painted in, as 21 of the benchmark's 289 training
    labels carry them: pure blue anywhere, and off-palette magentas/reds/greys inside the labelled area;
    and the pixels painted."""
    gt = cv2.imread(str(KITTI / "gt_image_2/um_road_000000.png"), cv2.IMREAD_UNCHANGED)
    rng = np.random.default_rng(seed)
    painted = np.zeros(gt.shape[:2], bool)
    h, w = gt.shape[:2]
    for colour in ((255, 0, 0), (254, 3, 250), (0, 7, 200), (30, 30, 30), (255, 255, 0)):  # BGR
        ys, xs = rng.integers(0, h, 40), rng.integers(0, w, 40)
        gt[ys, xs] = colour
        painted[ys, xs] = True
    return gt, painted


def test_kitti_labels_decode_as_the_devkit_pixel_for_pixel():
    """The devkit (evaluateRoad.py, on cv2's BGR image): evaluated area = red channel > 0, road = blue
    channel > 0 there. Stray colours follow that rule instead of stopping the read; the palette's own
    colours keep their meaning (magenta road, red not road, black ignore)."""
    gt, painted = _kitti_with_strays()
    got = decode_label(gt, get_label_format("kitti"))
    valid, road = gt[..., 2] > 0, gt[..., 0] > 0
    assert np.array_equal(got == 1, valid & road)
    assert np.array_equal(got == 0, valid & ~road)
    assert np.array_equal(got == 255, ~valid)
    clean = cv2.imread(str(KITTI / "gt_image_2/um_road_000000.png"), cv2.IMREAD_UNCHANGED)
    palette = {(255, 0, 255): 1, (0, 0, 255): 0, (0, 0, 0): 255}  # BGR -> decoded
    for bgr, value in palette.items():
        assert (decode_label(clean, get_label_format("kitti"))[(clean == bgr).all(-1)] == value).all()
    assert painted.sum() > 100 and (got[painted & (gt[..., 2] == 0)] == 255).all()


def test_eval_on_a_label_with_stray_blue_equals_the_clean_label(tmp_path):
    """Pure blue pixels lie outside the devkit's evaluated area (red clear), so MaxF, AP and IoU on a label
    carrying them equal those on the clean label, even where the prediction is certain road there."""
    from vcprep.io import write_png

    clean = cv2.imread(str(KITTI / "gt_image_2/um_road_000000.png"), cv2.IMREAD_UNCHANGED)
    stray = clean.copy()
    ys, xs = np.nonzero(clean[..., 2] == 0)
    pick = np.random.default_rng(1).choice(len(ys), 8, replace=False)
    stray[ys[pick], xs[pick]] = (255, 0, 0)  # BGR pure blue: 8 pixels, as in um_road_000057.png
    prob = np.where(clean[..., 0] > 0, 200, 60).astype(np.uint8)
    prob[ys[pick], xs[pick]] = 255
    pred = tmp_path / "preds"
    pred.mkdir()
    write_png(pred / "um_000000_prob.png", prob, kind="mask")
    write_png(pred / "um_000000_mask.png", np.where(prob >= 128, 255, 0).astype(np.uint8), kind="mask")
    scores = []
    for name, label in (("clean", clean), ("stray", stray)):
        (tmp_path / name).mkdir()
        cv2.imwrite(str(tmp_path / name / "um_road_000000.png"), label)
        proc = run_cli("eval", pred, "--labels", tmp_path / name, "--label-format", "kitti", "--json", "-q",
                       prog="vctrain")
        assert proc.returncode == 0, proc.stderr
        scores.append(json.loads(proc.stdout))
    assert scores[0] == scores[1] and scores[0]["maxf"] > 0.99


def test_a_label_that_is_not_kitti_is_still_refused(tmp_path):
    """A grey picture is no KITTI label: one channel, or three equal ones (ids saved as an image)."""
    grey = cv2.imread(str(CAMVID_LABELS / sorted(p.name for p in CAMVID_LABELS.iterdir())[0]), cv2.IMREAD_UNCHANGED)
    with pytest.raises(Exception, match="needs a colour image"):
        decode_label(grey, get_label_format("kitti"), "x.png")
    with pytest.raises(Exception, match=r"label colour \(R,G,B\)=\((\d+),\1,\1\) at pixel .* not in format 'kitti'"):
        decode_label(cv2.merge([grey] * 3), get_label_format("kitti"), "x.png")
