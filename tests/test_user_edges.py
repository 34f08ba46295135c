"""The smaller rough edges a new user met (issue 72.7), each as the user met it: the Makefile run from
another folder, the shipped model named from another folder, and a mistyped name from a table."""
from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

from conftest import EXAMPLES, assert_one_error_line, run_cli

ROOT = Path(__file__).resolve().parent.parent
SHIPPED = ROOT / "models" / "road-all" / "road.pt"


def _make_n(cwd: Path, *args: str) -> subprocess.CompletedProcess:
    """``make -n ... demo`` as a user types it: not a sub-make of ``make test`` (whose MAKELEVEL would
    add 'Entering directory' lines naming the folder)."""
    env = {k: v for k, v in os.environ.items() if k not in ("MAKELEVEL", "MAKEFLAGS", "MFLAGS")}
    return subprocess.run(["make", "-n", *args, "demo"], capture_output=True, text=True, cwd=cwd, timeout=60, env=env)


def test_make_demo_runs_from_another_folder(tmp_path):
    """make -f /path/to/Makefile demo from another folder reads the repository's files (the dry run's
    commands name them, and they exist); at the repository root the commands are what they were."""
    proc = _make_n(tmp_path, "-f", str(ROOT / "Makefile"))
    assert proc.returncode == 0, proc.stderr
    named = {w.strip("'") for w in proc.stdout.split() if w.startswith((str(ROOT), f"'{ROOT}"))}
    for rel in ("examples/camvid/images", "examples/kitti/image_2", "examples/kitti/gt_image_2",
                "models/road-all/road.pt"):
        assert str(ROOT / rel) in named and (ROOT / rel).exists(), rel
    assert "--out out/demo/store" in proc.stdout  # the outputs go where make runs
    here = _make_n(ROOT)
    assert here.returncode == 0 and str(ROOT) not in here.stdout, here.stdout
    assert "--images examples/camvid/images --labels examples/camvid/labels" in here.stdout
    assert "predict models/road-all/road.pt examples/kitti/image_2" in here.stdout


def test_the_shipped_model_by_name_from_another_folder(tmp_path):
    from vctrain.cli.common import model_arg

    assert model_arg(Path("shipped")) == model_arg(Path("road-all")) == SHIPPED
    assert model_arg(Path("road-street")) == ROOT / "models" / "road-street" / "road.pt"
    # the models shipped before stay reachable by their names
    assert model_arg(Path("road-multicamera")) == ROOT / "models" / "road-multicamera" / "road.pt"
    proc = run_cli("predict", "shipped", EXAMPLES / "kitti/image_2/um_000000.png", "--out", "o", "--quiet",
                   prog="vctrain", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "o" / "um_000000_mask.png").is_file()
    # the README's path from another folder: refused, naming where the shipped model is and its name
    proc = run_cli("predict", "models/road-all/road.pt", EXAMPLES / "kitti/image_2", "--out", "o2",
                   prog="vctrain", cwd=tmp_path)
    assert_one_error_line(proc, "checkpoint not found", str(SHIPPED), "shipped")
    assert_one_error_line(run_cli("predict", "road-multicamra", EXAMPLES / "kitti/image_2", "--out", "o2",
                                  prog="vctrain", cwd=tmp_path), "did you mean 'road-multicamera'?")


@pytest.mark.parametrize("args,needle", [
    (("camera", "show", "camvdi"), "did you mean 'camvid'?"),
    (("warp", "--camera", "camvid", "--images", EXAMPLES / "camvid/images", "--labels", EXAMPLES / "camvid/labels",
      "--label-format", "camvd", "--out", "s"), "did you mean 'camvid'?"),
])
def test_a_mistyped_name_from_a_table_gets_a_suggestion(args, needle, tmp_path):
    proc = run_cli(*args, cwd=tmp_path)
    assert_one_error_line(proc, needle, "use one of")


def test_the_suggestion_is_one_helper():
    from vcprep.camera import load_camera
    from vcprep.errors import InputError, one_of

    with pytest.raises(InputError, match="did you mean 'kitti'"):
        load_camera("preset:kiti")

    assert one_of("rayz", ("extend", "rays", "hybrid")) == "did you mean 'rays'? use one of extend, rays, hybrid"
    assert one_of("zzz", ("a", "b"), "or a file") == "use one of a, b or a file"  # nothing close: the list alone


def test_fine_tuning_starts_from_the_shipped_model_by_name(tmp_path):
    """``fit --init shipped`` from another folder fine-tunes the shipped model (said before the first
    epoch, with its file); the README's path from another folder is refused naming it, before training."""
    from conftest import write_synthetic_dataset
    from vcprep.camera import PRESETS

    img, lab = write_synthetic_dataset(tmp_path / "d", PRESETS["camvid"].for_image_size((64, 48)), n=5)
    data = ["--baseline", "resize", "--images", img, "--labels", lab, "--label-format", "camvid", "--size", "64x64",
            "--batch-size", "4", "--epochs", "1", "--threads", "1"]
    proc = run_cli("fit", *data, "--init", "shipped", "--out", "ft.pt", prog="vctrain", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert f"fine-tuning {SHIPPED}" in proc.stderr.split("epoch 1/1")[0] and (tmp_path / "ft.pt").is_file()
    proc = run_cli("fit", *data, "--init", "models/road-all/road.pt", "--out", "ft2.pt", prog="vctrain",
                   cwd=tmp_path)
    assert_one_error_line(proc, "checkpoint not found", str(SHIPPED), "shipped")
    assert not (tmp_path / "ft2.pt").exists()
