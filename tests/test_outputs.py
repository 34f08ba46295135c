"""Two outputs, one per label definition (vctrain.training.outputs): road and drivable area.

Oracles: the set-valued cross entropy against the definition computed by hand in plain Python (math.exp,
math.log) on a tiny tensor; a one-output model's loss against torch's own F.cross_entropy, bit for bit;
and a small real training on rendered scenes of known geometry (vcprep.synthetic) where one store labels
the road and another the drivable area = the road plus a shoulder band either side (the same scene rendered
with a wider road): the road output must leave the band out where the drivable output takes it in.
"""
from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch
from torch.nn import functional as F

from vcprep.camera import PRESETS
from vcprep.dataset import list_dataset
from vcprep.errors import InputError
from vcprep.io import read_image, write_png
from vcprep.labels import LABEL_FORMATS, get_label_format
from vcprep.store import Store, WarpSettings, warp_dataset
from vcprep.synthetic import RoadScene, render_road

from conftest import assert_one_error_line, run_cli

from vctrain.training import (CLASS_SETS, TWO_OUTPUTS, RoadDataset, TrainConfig, encode, fit,  # noqa: E402
                              load_checkpoint, loss_of, output_probability, output_probability_np, save_checkpoint,
                              set_cross_entropy, store_samples)

torch.set_num_threads(1)
CAM = PRESETS["camvid"].resized(0.1)  # 96x72: --camera camvid scales to it
SHOULDER = 2.0   # metres of drivable shoulder either side of the 8 m road
ROAD_SPEC = "values:road=1;ignore=255"
DRIVABLE_SPEC = ROAD_SPEC + ";definition=drivable"


# -- label definitions ----------------------------------------------------------------------------------

def test_each_format_says_what_its_road_is():
    assert {n: f.definition for n, f in LABEL_FORMATS.items()} == {
        "camvid": "road", "kitti": "road", "cityscapes": "road", "bdd": "drivable", "idd": "drivable"}
    assert get_label_format(ROAD_SPEC).definition == "road"
    fmt = get_label_format(DRIVABLE_SPEC)
    assert (fmt.definition, fmt.road, fmt.ignore, fmt.name) == ("drivable", (1,), (255,), DRIVABLE_SPEC)
    with pytest.raises(InputError, match="unknown label definition 'lane'"):
        get_label_format("values:road=1;definition=lane")


def test_encode_offsets_drivable_labels_and_keeps_ignore():
    lab = np.array([[0, 1, 255]], dtype=np.uint8)
    assert encode(lab, "road") is lab
    assert encode(lab, "drivable").tolist() == [[2, 3, 255]]


# -- the loss ------------------------------------------------------------------------------------------

def _by_hand(logits: list[list[float]], codes: list[int]) -> float:
    """mean over labelled pixels of log(sum exp(all)) - log(sum exp(set)), the sets written out here."""
    sets = {0: (0, 1), 1: (2,), 2: (0,), 3: (1, 2)}
    terms = [math.log(sum(math.exp(v) for v in px)) - math.log(sum(math.exp(px[c]) for c in sets[code]))
             for px, code in zip(logits, codes) if code != 255]
    return sum(terms) / len(terms)


def test_set_cross_entropy_against_a_hand_computation():
    px = [[0.3, -1.2, 2.0], [1.5, 0.1, -0.4], [-0.7, 0.9, 0.2], [2.2, -0.3, 0.8], [0.0, 3.0, -2.0], [1.0, 1.0, 1.0]]
    codes = [0, 1, 2, 3, 255, 3]
    logits = torch.tensor(px, dtype=torch.float64).T.reshape(1, 3, 1, len(px))
    got = set_cross_entropy(logits, torch.tensor(codes).reshape(1, 1, -1))
    assert got.item() == pytest.approx(_by_hand(px, codes), abs=1e-12)
    assert [tuple(i for i in range(3) if s[i]) for s in CLASS_SETS] == [(0, 1), (2,), (0,), (1, 2)]
    # every pixel ignored: NaN, as F.cross_entropy gives (the loop's step skips such a batch)
    assert math.isnan(set_cross_entropy(logits, torch.full((1, 1, len(px)), 255)).item())


def test_one_output_loss_is_torchs_cross_entropy_bit_for_bit():
    g = torch.Generator().manual_seed(3)
    logits = torch.randn(2, 2, 5, 7, generator=g)
    y = torch.randint(0, 2, (2, 5, 7), generator=g)
    y[0, :2] = 255
    w = torch.tensor([0.7, 1.9])
    assert torch.equal(loss_of(logits, y), F.cross_entropy(logits, y, ignore_index=255))
    assert torch.equal(loss_of(logits, y, w), F.cross_entropy(logits, y, weight=w, ignore_index=255))


def test_output_probabilities_of_three_classes():
    logits = torch.tensor([[0.2, -1.0], [1.1, 0.4], [-0.3, 2.5]]).reshape(1, 3, 1, 2)
    e = logits.exp()
    road = output_probability(logits, "road")
    drivable = output_probability(logits, "drivable")
    assert torch.allclose(road, e[:, 2] / e.sum(1))
    assert torch.allclose(drivable, (e[:, 1] + e[:, 2]) / e.sum(1))
    assert np.allclose(output_probability_np(logits[0].numpy(), "drivable"), drivable[0].numpy(), atol=1e-6)
    two = torch.tensor([[0.2], [1.1]]).reshape(1, 2, 1, 1)  # a one-output model: softmax class 1
    assert torch.equal(output_probability(two, "road"), torch.softmax(two, 1)[:, 1])


# -- a real training on two stores of two definitions ---------------------------------------------------

def _frame(i: int, shoulder: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Rendered frame ``i`` and its label: the road, or with ``shoulder`` the road widened by it either side."""
    scene, pan = RoadScene(offset=-1.5 + 0.5 * (i % 7), texture_seed=i), -4.0 + 1.1 * (i % 8)
    img, lab = render_road(CAM, scene, pan=pan)
    if shoulder:
        lab = render_road(CAM, replace(scene, width=scene.width + 2 * shoulder), pan=pan)[1]
    return img, lab


def _store(root: Path, name: str, spec: str, shoulder: float, ids: range) -> Path:
    for sub in ("images", "labels"):
        (root / name / sub).mkdir(parents=True)
    for i in ids:
        img, lab = _frame(i, shoulder)
        write_png(root / name / "images" / f"t_{i}.png", img)
        write_png(root / name / "labels" / f"t_{i}.png", lab)
    fmt = get_label_format(spec)
    warp_dataset(list_dataset(root / name / "images", root / name / "labels", fmt), root / f"{name}_store",
                 WarpSettings(CAM, PRESETS["virtual"], 0.02, fmt, completion="projective", progress=False))
    return root / f"{name}_store"


@pytest.fixture(scope="module")
def two(tmp_path_factory) -> Path:
    """A two-output resfpn (width 8) trained 6 epochs on a road store and a drivable store of 8 frames each."""
    root = tmp_path_factory.mktemp("two_outputs")
    stores = [str(_store(root, "road", ROAD_SPEC, 0.0, range(0, 8))),
              str(_store(root, "drivable", DRIVABLE_SPEC, SHOULDER, range(8, 16)))]
    fit(TrainConfig(stores=stores, out=str(root / "two.pt"), base_width=8, epochs=6, batch_size=4, val_fraction=0,
                    progress=False, device="cpu", outputs="road,drivable"))
    return root


def test_store_items_carry_their_definition_to_the_targets(two):
    samples = store_samples(Store.open(two / "drivable_store"))
    assert {s.definition for s in samples} == {"drivable"}
    assert {s.definition for s in store_samples(Store.open(two / "road_store"))} == {"road"}
    size = Store.open(two / "drivable_store").store_size
    one, both = RoadDataset(samples[:1], size), RoadDataset(samples[:1], size, outputs=TWO_OUTPUTS)
    y1, y2 = one[0][1].numpy(), both[0][1].numpy()
    assert set(np.unique(y1)) <= {0, 1, 255} and (y1 == 1).any()  # one output: the labels as before
    assert np.array_equal(y2, encode(y1.astype(np.uint8), "drivable"))


def test_checkpoint_records_two_outputs(two):
    ck = load_checkpoint(two / "two.pt")
    assert ck["model_args"]["num_classes"] == 3
    assert ck["data"]["outputs"] == ["road", "drivable"] and ck["config"]["outputs"] == "road,drivable"


def test_the_road_output_leaves_the_shoulder_out_and_drivable_takes_it_in(two, tmp_path):
    """predict --output road and --output drivable on new frames: both run, drivable's mask holds road's,
    and on the shoulder band (drivable, not road) drivable's mask covers far more than road's."""
    frames = tmp_path / "frames"
    frames.mkdir()
    truth = {}
    for i in (40, 41, 42):
        img, road = _frame(i)
        truth[f"t_{i}"] = (road == 1, (_frame(i, SHOULDER)[1] == 1) & (road == 0))
        write_png(frames / f"t_{i}.png", img)
    masks = {}
    for output in ("road", "drivable"):
        r = run_cli("predict", two / "two.pt", frames, "--camera", "camvid", "--engine", "torch", "--output", output,
                    "--out", tmp_path / output, "--quiet", prog="vctrain")
        assert r.returncode == 0, r.stderr
        masks[output] = {k: read_image(tmp_path / output / f"{k}_mask.png", label=True).array > 0 for k in truth}
    road_m, driv_m = (np.stack([masks[o][k] for k in truth]) for o in ("road", "drivable"))
    road_t, band = (np.stack([truth[k][j] for k in truth]) for j in (0, 1))
    assert (driv_m | ~road_m).all()  # P(drivable) = p1 + p2 >= p2 = P(road)
    assert driv_m.sum() > road_m.sum()
    assert road_m[road_t].mean() > 0.7 and driv_m[road_t].mean() > 0.7
    assert driv_m[band].mean() - road_m[band].mean() > 0.25, (driv_m[band].mean(), road_m[band].mean())


def test_the_record_says_the_output_and_keeps_the_outputs_apart(two, tmp_path):
    """predict.json names a drivable run's output; road masks of the same model written into that folder
    next are another model's masks: they replace the record (eval never mixes the two), which names no output."""
    import json

    write_png(tmp_path / "t_45.png", _frame(45)[0])
    record = lambda: json.loads((tmp_path / "p" / "predict.json").read_text())
    for output in ("drivable", "road"):
        r = run_cli("predict", two / "two.pt", tmp_path / "t_45.png", "--camera", "camvid", "--engine", "torch",
                    "--output", output, "--out", tmp_path / "p", prog="vctrain")
        assert r.returncode == 0, r.stderr
        assert (f"its {output} output" in r.stderr) == (output == "drivable")
        assert record().get("output", "road") == output and len(record()["runs"]) == 1
    assert "output" not in record()


def test_the_python_face_gives_the_output_asked(two):
    import vctrain

    img, _ = _frame(43)
    road = vctrain.load(two / "two.pt", engine="torch").segment(img, CAM).prob
    driv = vctrain.load(two / "two.pt", engine="torch", output="drivable").segment(img, CAM).prob
    assert (driv >= road - 1e-6).all() and (driv - road).max() > 0.2


def test_drivable_of_a_one_output_model_is_one_error_line(two, tmp_path):
    """A model of one output (a two-class network, as every model before) asked for drivable: refused."""
    from vctrain.networks import build_model

    ck = load_checkpoint(two / "two.pt")
    args = {**ck["model_args"], "num_classes": 2}
    data = {k: v for k, v in ck["data"].items() if k != "outputs"}
    save_checkpoint(tmp_path / "one.pt", {**ck, "model": build_model(args).state_dict(), "model_args": args,
                                          "data": data})
    write_png(tmp_path / "f.png", _frame(44)[0])
    r = run_cli("predict", tmp_path / "one.pt", tmp_path / "f.png", "--camera", "camvid", "--output", "drivable",
                "--out", tmp_path / "p", prog="vctrain")
    assert_one_error_line(r, "one.pt", "output road, not 'drivable'", "--outputs road,drivable")
    import vctrain

    with pytest.raises(InputError, match="not 'drivable'"):
        vctrain.load(tmp_path / "one.pt", output="drivable")


def test_median_freq_weights_with_two_outputs_are_refused(two, tmp_path):
    cfg = TrainConfig(stores=[str(two / "road_store")], out=str(tmp_path / "m.pt"), base_width=8, epochs=1,
                      progress=False, device="cpu", outputs="road,drivable", class_weights="median-freq")
    with pytest.raises(InputError, match="median-freq are for one output"):
        fit(cfg)
    with pytest.raises(InputError, match="unknown outputs 'drivable'"):
        fit(replace(cfg, outputs="drivable", class_weights="none"))


def test_exported_graph_computes_the_output_it_was_exported_for(two, tmp_path):
    """The graph of --output drivable against the library's P(drivable) on the same frame (mount pose), and
    the graph refuses the other output."""
    pytest.importorskip("onnxruntime")
    from vctrain.deploy import OnnxPredictor, export_onnx
    from vctrain.predict import Predictor, predict_images

    (tmp_path / "frames").mkdir()
    img = _frame(45)[0]
    write_png(tmp_path / "frames" / "f.png", img)
    info = export_onnx(two / "two.pt", CAM, tmp_path / "drivable.onnx", output="drivable")
    assert info["prob_of"] == "drivable" and info["max_abs_diff_vs_torch"] < 1e-4
    graph = OnnxPredictor(tmp_path / "drivable.onnx", threads=1, output="drivable")
    lib = {}
    for output in ("road", "drivable"):
        p = Predictor(two / "two.pt", "cpu", output=output)
        predict_images(p, [tmp_path / "frames"], tmp_path / output, CAM, progress=False, within="none",
                       keep_store=tmp_path / f"kept_{output}")
        st = Store.open(tmp_path / f"kept_{output}")
        lib[output] = p.store_item(st, st.get("f"))
    got = graph.road_probability(img)
    assert np.abs(got - lib["drivable"]).max() <= 1e-3
    assert np.abs(got - lib["road"]).max() > 0.2  # (the other output is another map)
    with pytest.raises(InputError, match=r"graph computes P\(drivable\), not P\(road\)"):
        OnnxPredictor(tmp_path / "drivable.onnx", threads=1)
