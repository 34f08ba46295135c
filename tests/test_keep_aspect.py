"""``keep_aspect`` (issue 82's pixel budget of wide frames): a resize baseline that trains and predicts
every frame at the working size's pixel count at the frame's own aspect, a batch frames of one size
(vctrain.training.parts.AspectParts), instead of squashing every frame to the working size.

Oracle: the working size of a frame of aspect a under a budget of N pixels is (sqrt(N a), sqrt(N / a))
rounded, computed here from the formula; the network's input is read by a forward hook."""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from vcprep.camera import PRESETS
from vcprep.errors import InputError
from vctrain.predict import Predictor
from vctrain.training import AspectParts, TrainConfig, fit, load_checkpoint, prepare_data, training_sets, view_batches
from vctrain.training.loop import _epoch_loader

torch.set_num_threads(1)
BUDGET = (128, 96)          # the working size: 12,288 pixels
WIDE, NARROW = (414, 125), (160, 120)  # KITTI's camera at a third (aspect 3.31) and CamVid's (4:3)


def _expected(frame: tuple[int, int]) -> tuple[int, int]:
    n, a = BUDGET[0] * BUDGET[1], frame[0] / frame[1]
    return round(math.sqrt(n * a)), round(math.sqrt(n / a))


@pytest.fixture(scope="module")
def two_cameras(tmp_path_factory):
    """One folder of rendered road frames from two cameras (3 wide, 3 narrow) and a width-4 resize
    model trained on them with keep_aspect for one epoch."""
    from conftest import write_synthetic_dataset

    root = tmp_path_factory.mktemp("aspect")
    images, labels = root / "all" / "images", root / "all" / "labels"
    images.mkdir(parents=True)
    labels.mkdir()
    for tag, cam, size in (("w", "kitti", WIDE), ("n", "camvid", NARROW)):
        img, lab = write_synthetic_dataset(root / tag, PRESETS[cam].for_image_size(size), n=3)
        for p in sorted(img.glob("*.png")):
            shutil.copy(p, images / f"{tag}_{p.name}")
            shutil.copy(lab / p.name, labels / f"{tag}_{p.name}")
    cfg = TrainConfig(baseline="resize", images=str(images), labels=str(labels), label_format="camvid",
                      size=BUDGET, keep_aspect=True, out=str(root / "aspect.pt"), base_width=4, epochs=1,
                      batch_size=2, val_fraction=0, progress=False, device="cpu")
    fit(cfg)
    return root, cfg


def test_each_frame_trains_at_the_budget_at_its_own_aspect_a_batch_one_size(two_cameras):
    root, cfg = two_cameras
    train_s, val_s, info = prepare_data(cfg)
    assert info["keep_aspect"] and info["input_size"] == list(BUDGET)
    train_ds, _ = training_sets(cfg, train_s, val_s, info)
    assert isinstance(train_ds, AspectParts)
    wide, narrow = _expected(WIDE), _expected(NARROW)
    assert wide == (202, 61) and narrow == BUDGET  # (the oracle's figures: 12,322 and 12,288 pixels)
    assert sorted(train_ds.sizes) == sorted([wide, narrow])
    for part, size in zip(train_ds.parts, train_ds.sizes):
        assert part.size == size
        assert {s.id[0] for s in part.samples} == ({"w"} if size == wide else {"n"})
        assert part.crop == (round(size[0] * 4 / 9), size[1])  # the recipe's window: 4/9 of the width, full height
    # the trainer's batches: one size each, both sizes every epoch, every item once
    loader = _epoch_loader(train_ds, cfg, 0, 0, 1, 2)
    shapes, seen = set(), []
    for batch in loader.batch_sampler:
        assert len({train_ds.view(i) for i in batch}) == 1
        seen += batch
    for x, y in loader:
        assert x.shape[0] == y.shape[0] and x.shape[-2:] == y.shape[-2:]
        shapes.add(tuple(x.shape[-2:]))
    assert shapes == {(wide[1], round(wide[0] * 4 / 9)), (narrow[1], round(narrow[0] * 4 / 9))}
    assert sorted(seen) == list(range(6))


def test_parts_batches_keep_the_orders_randomness():
    from vctrain.training import RoadDataset, Sample

    parts = [RoadDataset([Sample(f"{v}{i}", Path("x"), None) for i in range(n)], (64, 32)) for v, n in (("a", 3), ("b", 0), ("c", 2))]
    from vctrain.training import Parts

    whole = Parts(*parts)
    assert [whole.view(i) for i in range(5)] == [0, 0, 0, 2, 2]  # (an empty part holds no item)
    assert view_batches(whole, [3, 0, 4, 1, 2], 2) == [[3, 4], [0, 1], [2]]


def test_a_keep_aspect_model_predicts_each_frame_at_its_own_aspect(two_cameras):
    root, _ = two_cameras
    ck = load_checkpoint(root / "aspect.pt")
    assert ck["data"]["keep_aspect"] is True and ck["config"]["keep_aspect"] is True
    model = Predictor(root / "aspect.pt", device="cpu")
    seen = []
    hook = model.model.register_forward_hook(lambda m, inp, out: seen.append(tuple(inp[0].shape[-2:])))
    try:
        for frame in (WIDE, NARROW, (100, 100)):
            img = np.random.default_rng(0).integers(0, 255, (frame[1], frame[0], 3), dtype=np.uint8)
            prob = model.road_probability(img)
            assert prob.shape == (frame[1], frame[0])
            assert model.frame_working_size(frame) == _expected(frame)
    finally:
        hook.remove()
    assert seen == [(61, 202), (96, 128), (111, 111)]  # (h, w): 12,288 pixels at each frame's aspect


def test_keep_aspect_is_refused_where_items_have_one_size(tmp_path):
    from vcprep.dataset import list_dataset
    from vcprep.labels import get_label_format
    from vcprep.store import WarpSettings, warp_dataset
    from conftest import write_synthetic_dataset

    cam = PRESETS["camvid"].for_image_size((96, 72))
    img, lab = write_synthetic_dataset(tmp_path / "src", cam, n=2)
    fmt = get_label_format("camvid")
    warp_dataset(list_dataset(img, lab, fmt), tmp_path / "store", WarpSettings(cam, PRESETS["virtual"], 0.02, fmt, progress=False))
    with pytest.raises(InputError, match="keep-aspect is for the resize baseline"):
        prepare_data(TrainConfig(stores=[str(tmp_path / "store")], keep_aspect=True, val_fraction=0))
    assert "keep_aspect" not in prepare_data(TrainConfig(stores=[str(tmp_path / "store")], val_fraction=0))[2]


def test_fine_tuning_a_keep_aspect_model_keeps_the_frames_aspect(two_cameras, tmp_path):
    """fit --init of a keep_aspect model trains at its budget and at the frames' own aspect, as it learnt."""
    from dataclasses import replace

    root, cfg = two_cameras
    tuned = replace(cfg, keep_aspect=False, size=None, init=str(root / "aspect.pt"), out=str(tmp_path / "ft.pt"),
                    val_fraction=None, base_width=None, lr=None)
    fit(tuned)
    ck = load_checkpoint(tmp_path / "ft.pt")
    assert ck["data"]["keep_aspect"] is True and ck["data"]["input_size"] == list(BUDGET)


def test_an_exported_keep_aspect_model_runs_the_network_at_the_frames_aspect(two_cameras, tmp_path):
    """vctrain export of a keep_aspect model for wide frames: the graph's P(road) is the Predictor's (each frame
    at its own aspect), not that of the frame squashed to the pixel budget's 128x96."""
    pytest.importorskip("onnxruntime")
    import onnxruntime as ort

    from vctrain.deploy import export_onnx

    root, _ = two_cameras
    export_onnx(root / "aspect.pt", None, tmp_path / "wide.onnx", size=WIDE)
    img = np.random.default_rng(1).integers(0, 255, (WIDE[1], WIDE[0], 3), dtype=np.uint8)
    got = ort.InferenceSession(str(tmp_path / "wide.onnx")).run(None, {"frame": img})[0].reshape(WIDE[1], WIDE[0])
    model = Predictor(root / "aspect.pt", device="cpu")
    aspect, squashed = model.road_probability(img), model.road_probability(img, size=BUDGET)
    assert np.abs(got - aspect).max() < 1e-3 < np.abs(got - squashed).max()
