"""Labels that make no sense under their format (vcprep.labels.RoadShare; issue 52 item 6): over a set,
road that covers none or nearly all of the labelled pixels, or lies mostly in the frames' upper half,
is a warning in ``vcprep warp`` and ``vctrain eval``. Oracles: labels rendered with known geometry
(vcprep.synthetic: road below the horizon), and the shipped CamVid labels (3 road, 1 building)."""
from __future__ import annotations

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
