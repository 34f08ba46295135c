"""The README's example pipeline (examples/Makefile) runs end to end on the shipped frames:
warp, fit (virtual camera and resize baseline), predict on another camera, eval."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
def test_examples_makefile_end_to_end(tmp_path):
    out = tmp_path / "exp"
    proc = subprocess.run(["make", "-f", "examples/Makefile", f"BIN={Path(sys.executable).parent}", f"OUT={out}",
                           "EPOCHS=1", "SIZE=172x88"], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    for cond in ("vc", "resize"):
        metrics = json.loads((out / f"eval_{cond}.json").read_text())
        assert {"iou", "precision", "recall", "f1", "maxf", "ap"} <= set(metrics)
        assert all(0.0 <= metrics[k] <= 1.0 for k in ("iou", "precision", "recall", "f1", "maxf", "ap"))
        assert (out / f"pred_{cond}" / "um_000000_mask.png").is_file()
    # every step is a file target: a second run does nothing
    again = subprocess.run(["make", "-f", "examples/Makefile", f"BIN={Path(sys.executable).parent}", f"OUT={out}",
                            "EPOCHS=1", "SIZE=172x88", "-q", f"{out}/eval_vc.json", f"{out}/eval_resize.json"],
                           cwd=ROOT, capture_output=True, text=True)
    assert again.returncode == 0, again.stdout + again.stderr
