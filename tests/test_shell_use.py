"""Shell use of vcprep and vctrain (issue 27, a newcomer's first hour): pipes that close early,
output folders, missing data folders, warnings with a verdict, help texts, counts in summaries.

Every test runs the installed commands (subprocess, real pipes) except the help walk, which
renders every command's --help through Typer's CliRunner.
"""
from __future__ import annotations

import json
import os
import re
import statistics
import subprocess
from pathlib import Path

import cv2
import pytest
import typer
from typer.testing import CliRunner


from conftest import PAPER_STORE, BIN, EXAMPLES, assert_one_error_line, run_cli, write_synthetic_dataset

ROOT = EXAMPLES.parent
KITTI = EXAMPLES / "kitti"


@pytest.fixture(scope="module")
def store(tmp_path_factory) -> Path:
    """The demo's store: the three CamVid example frames and the KITTI frame (688x350, 4 items)."""
    out = tmp_path_factory.mktemp("shell") / "store"
    for args in (["--camera", "camvid", "--images", EXAMPLES / "camvid/images", "--labels", EXAMPLES / "camvid/labels",
                  "--label-format", "camvid"],
                 ["--camera", KITTI / "calib/um_000000.txt", "--images", KITTI / "image_2", "--labels",
                  KITTI / "gt_image_2", "--label-format", "kitti"]):
        proc = run_cli("warp", *args, "--out", out, "--quiet")
        assert proc.returncode == 0, proc.stderr
    return out


def _shell(script: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """``script`` under bash with pipefail, the commands of .venv/bin first on PATH."""
    env = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ['PATH']}"}
    return subprocess.run(["bash", "-o", "pipefail", "-c", script], capture_output=True, text=True, cwd=cwd, env=env,
                          timeout=300)


def _to_closed_pipe(prog: str, *args) -> subprocess.CompletedProcess:
    """Run the command with stdout a pipe whose reader is already gone: its first write to
    stdout fails with EPIPE, every time (what '| head -1' does once head has its line)."""
    r, w = os.pipe()
    os.close(r)
    try:
        return subprocess.run([str(BIN / prog), *map(str, args)], stdout=w, stderr=subprocess.PIPE, text=True,
                              timeout=300)
    finally:
        os.close(w)


# ---------------------------------------------------------------- 1. pipes that close early
STREAMING = [
    ("vcprep", "store", "show", "{store}", "--json"),
    ("vcprep", "store", "show", "{store}"),
    ("vcprep", "store", "info", "{store}"),
    ("vcprep", "cameras", "--json"),
    ("vcprep", "camera", "show", "camvid"),
    ("vcprep", "vp", "--camera", "camvid", str(EXAMPLES / "camvid/images")),
    ("vcprep", "warp", "--help"),
    ("vctrain", "version"),
    ("vctrain", "fit", "--help"),
]


@pytest.mark.parametrize("cmd", STREAMING, ids=lambda c: " ".join(c[:3]))
def test_closed_stdout_is_a_normal_end(store, cmd):
    proc = _to_closed_pipe(cmd[0], *(a.format(store=store) for a in cmd[1:]))
    assert proc.returncode == 0, proc.stderr
    assert "Error" not in proc.stderr and "Traceback" not in proc.stderr and "Exception ignored" not in proc.stderr


def test_head_1_under_pipefail_exits_0_with_the_first_line(store):
    proc = _shell(f"vcprep store show '{store}' --json | head -1")
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["id"] == "0001TP_007170"
    proc = _shell("vcprep cameras | head -1 && vctrain fit --help | head -1")
    assert proc.returncode == 0, proc.stderr
    first, usage = proc.stdout.splitlines()
    assert first.split()[:2] == ["preset", "size"] and usage == "Usage: vctrain fit [OPTIONS] [stores]..."


def test_pipe_in_a_makefile_recipe(store, tmp_path):
    (tmp_path / "Makefile").write_text(
        "SHELL := bash\n.SHELLFLAGS := -o pipefail -c\n"
        f"first.json:\n\t{BIN}/vcprep store show {store} --json | head -1 > $@\n")
    proc = subprocess.run(["make", "-s"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert json.loads((tmp_path / "first.json").read_text())["id"] == "0001TP_007170"


def test_an_error_keeps_its_exit_code_when_stdout_is_closed(tmp_path):
    proc = _to_closed_pipe("vcprep", "store", "show", tmp_path / "missing", "--json")
    assert_one_error_line(proc, "missing", "no such store")
    assert proc.returncode == 1


# ---------------------------------------------------------------- 2, 3, 7: the first-hour fit path
@pytest.fixture(scope="module")
def trained(store, tmp_path_factory) -> tuple[Path, subprocess.CompletedProcess]:
    """README's first hour, step 4: 'vctrain fit STORE --size 344x176 --out runs/mine.pt', runs/
    missing (one epoch: the path and the messages, not the model)."""
    cwd = tmp_path_factory.mktemp("first_hour")
    proc = run_cli("fit", store, "--size", "344x176", "--out", "runs/mine.pt", "--epochs", "1",
                   "--val-fraction", "0", "--device", "cpu", prog="vctrain", cwd=cwd)
    return cwd, proc


def test_fit_creates_the_output_folder(trained):
    cwd, proc = trained
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "runs/mine.pt"
    assert sorted(p.name for p in (cwd / "runs").iterdir()) == ["mine.last.pt", "mine.log.jsonl", "mine.pt"]
    assert "1 epoch," in proc.stderr and "1 epochs" not in proc.stderr  # 7.


@pytest.mark.parametrize("prog, args", [
    ("vcprep", ["figure", "warp", "{store}", "-o", "{new}/fig.png"]),
    ("vcprep", ["prior", "{store}", "-o", "{new}/prior.npy"]),
    ("vcprep", ["camera", "design", "camvid", "kitti", "-o", "{new}/virtual.yaml"]),
    ("vcprep", ["vp", "--camera", "camvid", str(EXAMPLES / "camvid/images"), "-o", "{new}/vps.csv"]),
])
def test_file_outputs_create_their_folder(store, tmp_path, prog, args):
    new = tmp_path / "a" / "b"
    proc = run_cli(*(a.format(store=store, new=new) for a in args), prog=prog)
    assert proc.returncode == 0, proc.stderr
    assert (new / Path(args[-1]).name).is_file()


def test_a_file_in_the_way_of_the_output_folder_is_one_error_line(store, tmp_path):
    (tmp_path / "runs").write_text("not a folder")
    proc = run_cli("figure", "warp", store, "-o", tmp_path / "runs" / "fig.png")
    assert_one_error_line(proc, str(tmp_path / "runs"), "a file is in the way")


def test_fit_time_is_stated_next_to_the_command():
    """The time claim holds as written: README and fit --help state the measured minutes of a model of
    the default design (benchmarks/what_a_user_gets/results/user_route.json: the README route's own
    fits, 305 CamVid frames, 2 cores, the median)."""
    fits = json.loads((ROOT / "benchmarks/what_a_user_gets/results/user_route.json").read_text())["fit_seconds"]
    minutes = round(statistics.median(sum(fits.values(), [])) / 60)
    help_text = " ".join(CliRunner().invoke(_apps()["vctrain"], ["fit", "--help"]).stdout.split())
    assert "in minutes" not in help_text
    assert f"305 CamVid frames in about {minutes} min on 2 cores at the default store's 638x271" in help_text
    assert f"vctrain fit stores/camvid_train --out runs/vc.pt # about {minutes} min on 2 cores" in help_text
    assert f"from scratch; 305 CamVid frames in about {minutes} min on 2 cores)" in help_text  # --model's help
    lite = json.loads((ROOT / "benchmarks/what_a_user_gets/results/user_route_lite0fpn.json").read_text())["fit_seconds"]
    assert f"3.0 M; about {round(statistics.median(lite['vc']) / 60)} min, level with resfpn" in help_text
    readme = (ROOT / "README.md").read_text()
    hour = " ".join(readme[readme.index("## Your first hour"):readme.index("What each command writes")].split())
    assert "`vctrain fit stores/mine --out runs/mine.pt`" in hour
    assert f"About **{minutes} minutes** a model for 305 CamVid frames on 2 CPU cores" in hour
    assert "in minutes" not in readme


def test_predict_and_eval_count_in_the_singular(trained):
    cwd, fit = trained
    assert fit.returncode == 0, fit.stderr
    proc = run_cli("predict", "runs/mine.pt", "--camera", KITTI / "calib/um_000000.txt", KITTI / "image_2",
                   "--out", "preds", prog="vctrain", cwd=cwd)
    assert proc.returncode == 0, proc.stderr
    assert "preds: 1 image predicted (virtual model;" in proc.stderr
    proc = run_cli("eval", "preds", "--labels", KITTI / "gt_image_2", "--label-format", "kitti", prog="vctrain", cwd=cwd)
    assert proc.returncode == 0, proc.stderr
    assert "preds: 1 image evaluated" in proc.stderr


def test_warp_and_vp_count_in_the_singular(tmp_path):
    proc = run_cli("warp", "--camera", KITTI / "calib/um_000000.txt", "--images", KITTI / "image_2",
                   "--out", tmp_path / "s")
    assert proc.returncode == 0 and re.search(r"1 item: 1 built, 0 up to date, 0 failed \(store \d+x\d+, virtual camera "
                                              r"designed from um_000000: .*; road VPs: 1 accepted\)", proc.stderr)
    proc = run_cli("store", "show", tmp_path / "s")
    assert re.search(r"\n?1 item, \d+x\d+ at scale [\d.]+$", proc.stderr.strip()), proc.stderr
    proc = run_cli("vp", "--camera", "camvid", EXAMPLES / "camvid/images/0001TP_007170.png")
    assert proc.returncode == 0 and proc.stderr.startswith("1 image: "), proc.stderr


# ---------------------------------------------------------------- 4. missing data folders
@pytest.mark.parametrize("missing, named, fix", [
    ({"images", "labels"}, ["{images}, {labels}", "image and label folders not found"], "check --images and --labels"),
    ({"images"}, ["{images}", "image folder not found"], "check --images"),
    ({"labels"}, ["{labels}", "label folder not found"], "check --labels"),
])
@pytest.mark.parametrize("command", ["warp", "simulate", "fit --baseline resize"])
def test_missing_data_folders_are_named_images_first(tmp_path, missing, named, fix, command):
    images = tmp_path / "no_images" if "images" in missing else EXAMPLES / "camvid/images"
    labels = tmp_path / "no_labels" if "labels" in missing else EXAMPLES / "camvid/labels"
    data = ["--images", images, "--labels", labels, "--label-format", "camvid"]
    if command == "fit --baseline resize":
        proc = run_cli("fit", "--baseline", "resize", *data, "--out", tmp_path / "m.pt", prog="vctrain")
    else:
        proc = run_cli(command, "--camera", "camvid", *data, "--out", tmp_path / "out")
    assert_one_error_line(proc, *(n.format(images=images, labels=labels) for n in named), fix)
    line = proc.stderr.strip()
    assert line.startswith(f"Error: {images if 'images' in missing else labels}")
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------- 5. warnings with a verdict
def test_vp_outside_warnings_carry_a_verdict_and_are_counted(tmp_path, camvid_half):
    """Three items: the VP inside (nothing said), inside a thin ignore strip from the top edge
    (the rays start a few px from it: fine, counted only), above the image (28 px off: one
    warning line that says what to check and how, and whose command works)."""
    images, labels = write_synthetic_dataset(tmp_path / "ds", camvid_half, n=3)
    lab = cv2.imread(str(labels / "seq_0000.png"), cv2.IMREAD_UNCHANGED)
    lab[0:190, 236:246] = 11  # void from the top edge over the VP (240, 180)
    cv2.imwrite(str(labels / "seq_0000.png"), lab)
    (tmp_path / "vps.csv").write_text("id,u,v\nseq_0000,240,180\nseq_0001,240,-40\nseq_0002,240,180\n")
    st = tmp_path / "st"
    proc = run_cli("warp", "--camera", "camvid", "--images", images, "--labels", labels, "--label-format", "camvid",
                   *PAPER_STORE, "--within", tmp_path / "vps.csv", "--out", st)
    assert proc.returncode == 0, proc.stderr
    assert ("3 items: 3 built, 0 up to date, 0 failed (store 688x350; road VPs: 3 given); VP outside the covered region: 1 fine as is "
            "(completion rays start within 1% of the width from it), 1 to check (warnings below)") in proc.stderr
    warnings = [ln for ln in proc.stderr.splitlines() if ln.startswith("warning:")]
    assert len(warnings) == 1 and warnings[0].startswith("warning: seq_0001: VP outside the covered region; ")
    assert "if the VP is right the item is usable as is, if not give the right one with --within vps.csv" in warnings[0]
    recs = {r["id"]: r for r in map(json.loads, (st / "manifest.jsonl").read_text().splitlines())}
    assert [recs[i]["completion_vp_inside"] for i in ("seq_0000", "seq_0001", "seq_0002")] == [False, False, True]
    # the command the warning gives works as printed
    look = warnings[0].split("Look: ")[1].split(";")[0]
    proc = _shell(look, cwd=tmp_path)
    assert proc.returncode == 0 and (tmp_path / "seq_0001.png").is_file(), proc.stderr
    # 'vcprep complete' says the same when it rebuilds the items (replicate has no rays: nothing said)
    proc = run_cli("complete", st, "--method", "replicate")
    assert proc.returncode == 0 and "VP outside" not in proc.stderr and "warning:" not in proc.stderr, proc.stderr
    proc = run_cli("complete", st, "--method", "projective")
    assert "3 completed, 0 up to date, 0 failed (projective); VP outside the covered region: 1 fine as is" \
        in proc.stderr, proc.stderr


# ---------------------------------------------------------------- 6. help texts
def _apps() -> dict[str, typer.Typer]:
    import vcprep.cli
    import vctrain.cli

    return {"vcprep": vcprep.cli.app, "vctrain": vctrain.cli.app}


def _command_paths(cmd, path=()):
    yield list(path)
    for name, sub in sorted(getattr(cmd, "commands", {}).items()):
        yield from _command_paths(sub, (*path, name))


STRAY = ["%%", "\\n", "\\t", "\\b", "\\'", '\\"', "\x08", "%(", "[/", "[bold"]


def test_no_help_text_shows_a_stray_escape():
    runner = CliRunner()
    seen = 0
    for prog, app in _apps().items():
        for path in _command_paths(typer.main.get_command(app)):
            res = runner.invoke(app, [*path, "--help"], prog_name=prog)
            assert res.exit_code == 0, (prog, path, res.output)
            bad = [(s, ln) for ln in res.output.splitlines() for s in STRAY if s in ln]
            assert not bad, (prog, path, bad)
            seen += 1
    assert seen >= 30  # every command and group of both tools (23 + 7 today)


# ---------------------------------------------------------------- the demo figure's legend
def test_warp_figure_has_a_legend_line_with_the_red_plus(store, tmp_path):
    from vcprep.figures import COVERED_YELLOW, VP_RED, WARP_LEGEND

    assert any("vanishing point" in text for kind, text in WARP_LEGEND if kind == "vp")
    proc = run_cli("figure", "warp", store, "-o", tmp_path / "fig.png")
    assert proc.returncode == 0, proc.stderr
    fig = cv2.imread(str(tmp_path / "fig.png"))
    legend = fig[-28:]
    assert (legend == VP_RED).all(axis=2).sum() > 10 and (legend == COVERED_YELLOW).all(axis=2).sum() > 10
    assert (legend < 60).all(axis=2).sum() > 100  # the text
    makefile = (ROOT / "Makefile").read_text()
    assert "red + = the road vanishing point" in makefile.split("demo: $(STAMP)")[1].split("\n\n")[0]


def test_every_run_ends_with_one_summary_line_without_a_terminal(trained, tmp_path):
    """fit, predict and warp (stderr not a terminal here) each end with one line: how many, how long,
    how fast."""

    cwd, fit = trained
    assert re.search(r"runs/mine\.pt: \w+, 1 epoch, training [\d.]+ s/epoch \([\d.]+ img/s\), [\d.]+ s in all "
                     r"\(the command's wall clock\)", fit.stderr), fit.stderr  # (--val-fraction 0: no validation)
    proc = run_cli("predict", "runs/mine.pt", "--camera", KITTI / "calib/um_000000.txt", KITTI / "image_2",
                   "--out", "preds2", prog="vctrain", cwd=cwd)
    last = proc.stderr.strip().splitlines()[-1]
    assert re.fullmatch(r"preds2: 1 image predicted \(virtual model; [^()]+\); [\d.]+ s, [\d.]+ frames/s", last), last
    proc = run_cli("warp", "--camera", "camvid", "--images", EXAMPLES / "camvid/images", "--out", tmp_path / "s")
    assert re.search(r"3 items: 3 built, 0 up to date, 0 failed \(store 638x271, virtual camera designed from camvid: "
                     r"pan \+/-10 deg, tilt \+/-5 deg, 8 deg above the horizon, 172,800 px; road VPs: 3 accepted\); "
                     r"[\d.]+ s, [\d.]+ items/s$",
                     proc.stderr), proc.stderr
