"""The README's example pipeline (examples/Makefile) runs end to end on the shipped frames:
warp, fit (virtual camera and resize baseline), predict on another camera, eval; and it never goes
stale (issue 52): an edited label re-runs exactly warp, both fits, predict and eval (after the real
warp, what make would run next is read with `make -n`), a touched but unchanged image only the (no-op)
warp, and a second `make` runs nothing."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import pytest

ROOT = Path(__file__).resolve().parent.parent
BIN = Path(sys.executable).parent
EVERYTHING = {"warp", "fit vc", "fit resize", "predict vc", "predict resize", "eval vc", "eval resize"}

pytestmark = pytest.mark.skipif(shutil.which("make") is None, reason="needs make")


def _make(out: Path, camvid: Path, *goals: str, check: bool = True) -> subprocess.CompletedProcess:
    proc = subprocess.run(["make", "-f", "examples/Makefile", f"BIN={BIN}", f"OUT={out}", f"CAMVID={camvid}",
                           "EPOCHS=1", *goals], cwd=ROOT, capture_output=True, text=True, timeout=600)
    if check:
        assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    return proc


def _ran(proc: subprocess.CompletedProcess) -> set[str]:
    """The steps whose commands make ran (it echoes each command line)."""
    steps = set()
    for line in proc.stdout.splitlines():
        words = line.split()
        if not line.startswith(f"{BIN}/") or len(words) < 3:
            continue
        tool, cmd, arg = Path(words[0]).name, words[1], words[2]
        if (tool, cmd) == ("vcprep", "warp"):
            steps.add("warp")
        elif (tool, cmd) == ("vctrain", "fit"):
            steps.add("fit resize" if "--baseline resize" in line else "fit vc")
        elif (tool, cmd) in (("vctrain", "predict"), ("vctrain", "eval")):
            steps.add(f"{cmd} {'resize' if 'resize' in Path(arg).name else 'vc'}")
    return steps


def _outputs(out: Path) -> dict[str, int]:
    return {name: (out / name).stat().st_mtime_ns for name in
            ("vc.pt", "resize.pt", "pred_vc/.done", "pred_resize/.done", "eval_vc.json", "eval_resize.json")}


@pytest.fixture(scope="module")
def pipeline(tmp_path_factory) -> tuple[Path, Path, subprocess.CompletedProcess]:
    """The pipeline run once, on a copy of the CamVid example frames (the tests edit them)."""
    tmp = tmp_path_factory.mktemp("pipeline")
    camvid = tmp / "camvid"
    shutil.copytree(ROOT / "examples" / "camvid", camvid)
    out = tmp / "exp"
    return out, camvid, _make(out, camvid)


def test_examples_makefile_end_to_end(pipeline):
    out, camvid, first = pipeline
    assert _ran(first) == EVERYTHING
    for cond in ("vc", "resize"):
        metrics = json.loads((out / f"eval_{cond}.json").read_text())
        assert {"iou", "precision", "recall", "f1", "maxf", "ap"} <= set(metrics)
        assert all(0.0 <= metrics[k] <= 1.0 for k in ("iou", "precision", "recall", "f1", "maxf", "ap"))
        assert (out / f"pred_{cond}" / "um_000000_mask.png").is_file()
    # every step is a file target: a second run does nothing (make -q: every target is up to date)
    again = _make(out, camvid, "-q", f"{out}/eval_vc.json", f"{out}/eval_resize.json", check=False)
    assert again.returncode == 0, again.stdout + again.stderr


def test_an_edited_label_redoes_exactly_what_depends_on_it(pipeline):
    out, camvid, _ = pipeline
    assert _ran(_make(out, camvid)) == set()
    # a touched, unchanged image: warp looks (and writes nothing), nothing after it runs, then all is quiet
    before = _outputs(out)
    os.utime(camvid / "images" / "0016E5_05280.png")
    assert _ran(_make(out, camvid)) == {"warp"}
    assert _outputs(out) == before
    assert _ran(_make(out, camvid)) == set()
    # one label edited: warp, both fits, predict and eval, nothing else. The warp runs for real (the
    # store's content changes, so its stamp's time does); what make then decides from those times is
    # read with `make -n` (it prints what it would run, running nothing): both fits, both predicts and
    # both evals. The chain itself running for real, and a `make` after it doing nothing, are the
    # fixture's run and the checks above and in test_examples_makefile_end_to_end.
    stamp = out / "camvid" / "content.stamp"
    stamp_before = stamp.stat().st_mtime_ns
    path = camvid / "labels" / "0006R0_f02400.png"
    label = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    label[:20] = 3  # (camvid id 3: road)
    cv2.imwrite(str(path), label)
    assert _ran(_make(out, camvid, str(stamp))) == {"warp"}
    assert stamp.stat().st_mtime_ns > stamp_before
    assert _outputs(out) == before  # nothing after the warp ran
    assert _ran(_make(out, camvid, "-n")) == EVERYTHING - {"warp"}
    stale = _make(out, camvid, "-q", f"{out}/eval_vc.json", f"{out}/eval_resize.json", check=False)
    assert stale.returncode == 1, stale.stdout + stale.stderr  # make -q: a target is out of date
    assert _outputs(out) == before
    assert _ran(_make(out, camvid, str(stamp))) == set()  # the warp is not run twice
