"""The road model the project ships (models/road-multicamera/): it works out of the box on frames the
project ships, with a calibration file and with ``--camera estimate``, and its card states what was
measured (issue 34)."""
from __future__ import annotations

import json
import re
from pathlib import Path

from conftest import run_cli

ROOT = Path(__file__).resolve().parents[1]
FOLDER = ROOT / "models" / "road-multicamera"
MODEL = FOLDER / "road.pt"
EX = ROOT / "examples"


def _iou(pred: Path, labels: Path, fmt: str) -> float:
    proc = run_cli("eval", pred, "--labels", labels, "--label-format", fmt, "--json", "-q", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])["iou"]


def test_it_segments_the_kitti_frame_it_never_saw_with_its_calibration(tmp_path):
    proc = run_cli("predict", MODEL, EX / "kitti" / "image_2", "--camera", EX / "kitti" / "calib" / "um_000000.txt",
                   "--out", tmp_path, "--overlay", "-q", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "um_000000_overlay.png").is_file()
    # measured 0.447 (the card): the model marks the tram verge and the pavement as road (precision ~0.46,
    # recall ~0.98); a regression below 0.40 or a lost road (recall) fails
    assert _iou(tmp_path, EX / "kitti" / "gt_image_2", "kitti") >= 0.40


def test_it_segments_camvid_frames_with_an_estimated_camera(tmp_path):
    """``--camera estimate`` on the three CamVid example frames (all three from CamVid train, which the
    model was trained on: this checks the path a user without a calibration takes end to end, not
    accuracy on an unseen camera; the held-out figures are in the card). The shipped model reads
    frames as they are (the resize twin measured best): three frames are enough, nothing is estimated."""
    proc = run_cli("predict", MODEL, EX / "camvid" / "images", "--camera", "estimate", "--out", tmp_path, "-q",
                   prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert _iou(tmp_path, EX / "camvid" / "labels", "camvid") >= 0.80


def test_the_card_states_the_measured_figures_and_the_checkpoint_is_small():
    card = (FOLDER / "README.md").read_text()
    res = json.loads((FOLDER / "results.json").read_text())["headline"]
    for key, v in res.items():
        if re.fullmatch(r"(within|resize)_(camvid|cityscapes|idd|bdd|lums|kitti)", key) and v is not None:
            assert f"{v:.1f}" in card, key  # every held-out figure is in the card as measured (None: not run)
    assert any(v is not None for k, v in res.items() if k.startswith(res["shipped_condition"] + "_"))
    assert MODEL.stat().st_size <= 20e6
    assert "benchmarks/what_a_user_gets/shipped_model.py" in card  # the command that reproduces it


def test_the_card_states_the_measured_fine_tuning_figures():
    """The card's fine-tuning figures are the benchmarks': own_frames.py's on a camera the recipe
    never saw (every frame count it ran) and on one it knows, and the issue-34 study's gains; the
    fine-tuning as it runs by default since issue 72, finetune_guard.py's gain and worst seed per case
    and frame count (the README's route 2 gives them too: tests/test_docs.py)."""
    card = (FOLDER / "README.md").read_text()
    results = ROOT / "benchmarks" / "what_a_user_gets" / "results"
    unseen = json.loads((results / "own_frames_idd_unseen.json").read_text())
    h = unseen["headline"]
    for n in unseen["frames"].split(","):
        for key in (f"fine-tuned_n{n}_iou", f"zero-shot_n{n}_iou"):
            assert f"{h[key]:.1f}" in card, key
        assert f"{h[f'fine-tuned_minus_zero-shot_n{n}']:+.1f}" in card, n
    import importlib.util

    spec = importlib.util.spec_from_file_location("results_page", ROOT / "benchmarks" / "results_page.py")
    page = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(page)
    signed_points = page.headline.signed_points  # (as the README writes them)
    flat = " ".join(card.split())  # fine-tuning as it runs by default (finetune_guard.py): gain and worst seed
    guard = json.loads((results / "finetune_guard.json").read_text())
    h = guard["headline"]
    assert len(guard["seeds"]) == 3
    for key in [k for k in h if "_default_n" in k and k.endswith("_gain")]:
        n = key.split("_n")[1].split("_")[0]
        assert f"{signed_points(h[key])} (worst {signed_points(h[key.replace('_gain', '_worst')])}) with {n}" in flat, key
        assert f"({h[key.split('_default')[0] + '_zero-shot']:.1f})" in flat, key
    known = json.loads((results / "own_frames_idd_shipped.json").read_text())["headline"]
    assert f"{known['fine-tuned_minus_zero-shot_n60']:+.1f}" in card
    old = json.loads((results / "finetune.json").read_text())["headline"]
    for key in ("fine-tuned_minus_as-is", "fine-tuned_minus_scratch"):
        assert f"{old[key]:+.1f}" in card, key


def test_the_multicamera_recipe_is_the_shipped_models():
    """``--recipe multicamera`` trains what the shipped checkpoint records it was trained with (every
    setting the recipe fills), so a user's own multi-camera model follows the measured recipe."""
    import torch

    from vctrain.training import RECIPES, TrainConfig
    from vctrain.training import resolve_recipe

    shipped = torch.load(MODEL, map_location="cpu", weights_only=False)["config"]
    recipe = resolve_recipe(TrainConfig(recipe="multicamera")).to_dict()
    for key in RECIPES["multicamera"]:
        want = shipped[key]
        assert recipe[key] == (tuple(want) if isinstance(want, list) else want), key
    assert shipped["baseline"] == "resize" and recipe["pretrained"] is shipped["pretrained"] is True


STREET = ROOT / "models" / "road-street"
ALL = ROOT / "models" / "road-all"


def test_shipped_names_the_model_chosen_on_held_out_cameras_and_the_old_ones_stay_by_name():
    """Issue 82: `shipped` is road-all; road-street and road-multicamera, shipped before, are still reachable."""
    from vctrain.shipped import SHIPPED, shipped_models

    models = shipped_models()
    assert SHIPPED == "road-all" and models["shipped"] == ALL / "road.pt"
    assert models["road-street"] == STREET / "road.pt" and models["road-multicamera"] == MODEL


def test_the_shipped_model_segments_the_kitti_frame_and_camvid_frames(tmp_path):
    """The shipped model end to end on the frames the project ships: the KITTI road frame with its
    calibration (measured 56.6 on the held-out splits' run: the tram verge marked road; below 0.45 or a lost
    road fails) and CamVid's three example frames with an estimated camera."""
    proc = run_cli("predict", "shipped", EX / "kitti" / "image_2", "--camera", EX / "kitti" / "calib" / "um_000000.txt",
                   "--out", tmp_path / "k", "-q", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert _iou(tmp_path / "k", EX / "kitti" / "gt_image_2", "kitti") >= 0.45
    proc = run_cli("predict", "shipped", EX / "camvid" / "images", "--camera", "estimate", "--out", tmp_path / "c", "-q",
                   prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert _iou(tmp_path / "c", EX / "camvid" / "labels", "camvid") >= 0.80


def test_the_road_street_card_states_what_its_run_measured():
    """Every held-out figure of results.json (this model's and the replaced model's, and their difference) is in
    the card as measured, with the command that reproduces it; the checkpoint ships small."""
    card = (STREET / "README.md").read_text()
    res = json.loads((STREET / "results.json").read_text())
    h = res["headline"]
    assert res["candidate"] == "four" and res["datasets"] == ["camvid", "cityscapes", "kitti_semantics", "idd"]
    for t in res["splits"]:
        assert f"**{h[f'four_{t}']:.1f}** ({h[f'four_precision_{t}']:.1f} / {h[f'four_recall_{t}']:.1f})" in card, t
        assert f"{h[f'shipped_{t}']:.1f} ({h[f'shipped_precision_{t}']:.1f} / {h[f'shipped_recall_{t}']:.1f})" in card, t
        assert f"{h[f'four_{t}'] - h[f'shipped_{t}']:+.1f}".replace("-", "−") in card, t
    assert f"**{h['mean_four']:.1f}** | {h['mean_shipped']:.1f}" in card
    assert "benchmarks/what_a_user_gets/ship_mix.py --candidate four --epochs 30" in card
    assert (STREET / "road.pt").stat().st_size <= 20e6


def test_the_road_all_card_states_what_its_run_measured():
    """Every held-out figure of results.json (this model's, road-street's and road-multicamera's, and its
    differences to both) is in the card as measured, with the command that reproduces it; the checkpoint ships
    small."""
    card = (ALL / "README.md").read_text()
    res = json.loads((ALL / "results.json").read_text())
    h = res["headline"]
    assert res["candidate"] == "six" and res["epochs"] == 30 and set(res["also"]) == {"road-street"}
    assert res["datasets"] == ["camvid", "cityscapes", "kitti_semantics", "idd", "bdd", "lums"]
    pr = lambda who, t: f"({h[f'{who}_precision_{t}']:.1f} / {h[f'{who}_recall_{t}']:.1f})"
    cell = lambda who, t: f"{h[f'{who}_{t}']:.1f} {pr(who, t)}"
    for t in res["splits"]:
        row = next(ln for ln in card.splitlines() if f"| **{h[f'six_{t}']:.1f}** (" in ln and cell("road-street", t) in ln)
        assert f"**{h[f'six_{t}']:.1f}** {pr('six', t)} | {cell('road-street', t)} | {cell('shipped', t)} |" in row, t
        for who in ("road-street", "shipped"):
            assert f"{h[f'six_{t}'] - h[f'{who}_{t}']:+.1f}".replace("-", "−") in row, (t, who)
    assert f"**{h['mean_six']:.1f}** | {h['mean_road-street']:.1f} | {h['mean_shipped']:.1f} |" in card
    assert "ship_mix.py --candidate six --epochs 30 --seeds 0 --also models/road-street/road.pt --ship models/road-all" in card
    assert "GUARD" not in card and (ALL / "road.pt").stat().st_size <= 20e6
