"""Training on several stores: per-dataset balance of an epoch's draws (vctrain.training.trainset.epoch_order,
the trainer's epoch loader) and fine-tuning from a checkpoint (``vctrain fit --init``)."""
from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import torch
from typer.testing import CliRunner

from vcprep.store import WarpSettings, warp_dataset
from vcprep.dataset import list_dataset
from vcprep.camera import PRESETS
from vcprep.errors import InputError
from vcprep.io import write_png
from vcprep.labels import get_label_format
from vcprep.synthetic import RoadScene, render_road
from vctrain.training import RoadDataset, Sample, TrainConfig, epoch_order, fit, load_checkpoint, resolve_recipe
from vctrain.cli import app
from vctrain.training.loop import _epoch_loader

torch.set_num_threads(1)
FMT = "values:road=1"  # the synthetic labels: 0 not road, 1 road


def _dataset(sizes: dict[str, int]) -> RoadDataset:
    """A RoadDataset of len sum(sizes) whose items come from the named sources (nothing is read
    until an item is asked for: the order is all that is tested here)."""
    samples = [Sample(f"{s}{i}", Path(f"{s}{i}.png"), Path(f"{s}{i}_l.png"), source=s)
               for s, n in sizes.items() for i in range(n)]
    return RoadDataset(samples, (64, 32))


def _drawn(ds: RoadDataset, cfg: TrainConfig, epoch: int, world: int = 1) -> list[int]:
    """The item indices the trainer's loader visits in ``epoch`` (all ranks)."""
    out = []
    for rank in range(world):
        out += _epoch_loader(ds, cfg, epoch, rank, world, 4).dataset.indices
    return out


def test_balance_datasets_draws_each_store_equally_often():
    ds = _dataset({"large": 300, "small": 12})
    source = [s.source for s in ds.samples]
    cfg = TrainConfig(balance="datasets", seed=3)
    per_item = Counter()
    for epoch in range(10):
        got = _drawn(ds, cfg, epoch)
        assert len(got) == 312  # an epoch as long as with 'items': the step budget is unchanged
        c = Counter(source[i] for i in got)
        assert abs(c["large"] - c["small"]) <= 1  # 156 each (312 / 2)
        large = [i for i in got if source[i] == "large"]
        assert len(set(large)) == len(large)  # the large store: sampled without replacement
        per_item.update(got)
    # every small item drawn 156 * 10 / 12 = 130 times, give or take one an epoch
    assert all(abs(per_item[i] - 130) <= 10 for i in range(300, 312))
    assert _drawn(ds, cfg, 4) == _drawn(ds, cfg, 4)  # seeded: the same run draws the same
    assert _drawn(ds, cfg, 4) != _drawn(ds, TrainConfig(balance="datasets", seed=4), 4)
    # 'items' (the cpu recipe's default) visits every item once: the large store holds 96 % of the epoch
    items = _drawn(ds, resolve_recipe(TrainConfig(seed=3)), 0)
    assert sorted(items) == list(range(312))
    assert Counter(source[i] for i in items)["small"] == 12


def test_balance_datasets_split_across_processes_and_one_store():
    ds = _dataset({"a": 50, "b": 7, "c": 3})
    cfg = TrainConfig(balance="datasets", seed=0)
    whole = _drawn(ds, cfg, 2)
    split = _drawn(ds, cfg, 2, world=3)  # torchrun: each rank its share of the same epoch order
    assert Counter(split) == Counter(whole)
    c = Counter(s.source for s in (ds.samples[i] for i in whole))
    assert sorted(c.values()) == [20, 20, 20]
    one = _dataset({"a": 20})
    assert _drawn(one, cfg, 1) == _drawn(one, TrainConfig(seed=0), 1)  # one store: 'datasets' is 'items'
    with pytest.raises(InputError, match="unknown balance"):
        epoch_order(["a", "b"], "stores", torch.Generator().manual_seed(0))


def _store(root: Path, n: int, seed: int):
    cam = PRESETS["camvid"].resized(0.1)  # 96x72
    src = root / f"src{seed}"
    (src / "images").mkdir(parents=True)
    (src / "labels").mkdir()
    rng = np.random.default_rng(seed)
    for i in range(n):
        scene = RoadScene(offset=float(rng.uniform(-2, 2)), width=float(rng.uniform(6, 10)), texture_seed=seed * 10 + i)
        img, lab = render_road(cam, scene, pan=float(rng.uniform(-5, 5)))
        write_png(src / "images" / f"s{seed}_{i}.png", img)
        write_png(src / "labels" / f"s{seed}_{i}.png", lab)
    fmt = get_label_format(FMT)
    warp_dataset(list_dataset(src / "images", src / "labels", fmt), root / f"store{seed}",
                 WarpSettings(cam, PRESETS["virtual"], 0.02, fmt, progress=False))
    return str(root / f"store{seed}")


@pytest.fixture(scope="module")
def two_stores(tmp_path_factory):
    """Two synthetic stores of one virtual camera (110x56), 6 and 2 frames, and a width-4 model
    trained on both with balance=datasets."""
    root = tmp_path_factory.mktemp("multi")
    stores = [_store(root, 6, 0), _store(root, 2, 1)]
    cfg = TrainConfig(stores=stores, out=str(root / "a.pt"), base_width=4, epochs=1, batch_size=4, val_fraction=0,
                      progress=False, device="cpu", balance="datasets")
    fit(cfg)
    return root, stores


def test_fit_on_two_stores_records_the_balance(two_stores):
    root, stores = two_stores
    ck = load_checkpoint(root / "a.pt")
    assert ck["config"]["balance"] == "datasets"
    assert ck["data"]["train_items_per_source"] == {stores[0]: 6, stores[1]: 2}
    with pytest.raises(InputError, match="unknown balance"):
        fit(TrainConfig(stores=stores, out=str(root / "x.pt"), balance="cameras", progress=False))


def test_fit_init_starts_from_the_checkpoints_weights(two_stores, tmp_path):
    root, stores = two_stores
    a = load_checkpoint(root / "a.pt")
    # a learning rate too small to move a float32 weight: the fine-tuned parameters are the init's
    # (BatchNorm running statistics are buffers and do move); a fresh network of the seed is not
    r = CliRunner().invoke(app, ["fit", stores[1], "--init", str(root / "a.pt"), "--lr", "1e-30", "--schedule",
                                 "constant", "--weight-decay", "0", "--epochs", "1", "--val-fraction", "0",
                                 "--seed", "5", "--out", str(tmp_path / "b.pt"), "--quiet"])
    assert r.exit_code == 0, r.output
    fresh = tmp_path / "fresh.pt"
    fit(TrainConfig(stores=[stores[1]], out=str(fresh), base_width=4, epochs=1, lr=1e-30, schedule="constant",
                    weight_decay=0.0, val_fraction=0, seed=5, progress=False))
    b, c = load_checkpoint(tmp_path / "b.pt"), load_checkpoint(fresh)
    params = [k for k in a["model"] if "running" not in k and "num_batches" not in k]
    assert all(torch.equal(a["model"][k], b["model"][k]) for k in params)
    assert not all(torch.equal(a["model"][k], c["model"][k]) for k in params)
    assert b["model_args"] == a["model_args"]  # the init's network: resfpn at width 4, no --width given
    assert b["config"]["init"] == str(root / "a.pt") and b["init"]["epoch"] == 1 and len(b["init"]["sha256"]) == 64


def test_fit_init_without_lr_fine_tunes_at_a_tenth_of_the_checkpoints_rate(two_stores, tmp_path):
    root, stores = two_stores
    a = load_checkpoint(root / "a.pt")
    assert a["config"]["lr"] == 0.002  # the cpu recipe's, resolved into the checkpoint
    r = CliRunner().invoke(app, ["fit", stores[1], "--init", str(root / "a.pt"), "--epochs", "1", "--val-fraction",
                                 "0", "--out", str(tmp_path / "b.pt"), "--quiet"])
    assert r.exit_code == 0, r.output
    b = load_checkpoint(tmp_path / "b.pt")
    assert b["config"]["lr"] == pytest.approx(0.0002)
    assert max(row["lr"] for row in b["history"]) <= 0.0002 + 1e-12  # the schedule peaks at it
    # a run given --lr keeps it; a fresh run without --init keeps the recipe's
    r = CliRunner().invoke(app, ["fit", stores[1], "--init", str(root / "a.pt"), "--lr", "0.001", "--epochs", "1",
                                 "--val-fraction", "0", "--out", str(tmp_path / "c.pt"), "--quiet"])
    assert r.exit_code == 0, r.output
    assert load_checkpoint(tmp_path / "c.pt")["config"]["lr"] == 0.001
    # resumed without --lr (and without --init), the fine-tuning run keeps its own peak rate
    r = CliRunner().invoke(app, ["fit", stores[1], "--epochs", "2", "--val-fraction", "0", "--resume",
                                 str(tmp_path / "b.last.pt"), "--out", str(tmp_path / "b.pt"), "--quiet"])
    assert r.exit_code == 0, r.output
    resumed = load_checkpoint(tmp_path / "b.last.pt")
    assert resumed["epoch"] == 2 and resumed["config"]["lr"] == pytest.approx(0.0002)


def test_block_validation_holds_out_each_sources_last_items_in_name_order():
    from vctrain.training.trainset import validation_items

    # two drives, named out of order: the held-out items are each drive's last 20 % by name
    ids = [f"a_{i:03d}" for i in (4, 0, 9, 2, 7, 1, 8, 3, 6, 5)] + [f"b_{i:03d}" for i in (3, 0, 4, 1, 2)]
    sources = ["a"] * 10 + ["b"] * 5
    held = validation_items(ids, sources, 0.2, "block", seed=0)
    assert sorted(ids[i] for i in held) == ["a_008", "a_009", "b_004"]
    assert validation_items(ids, sources, 0.2, "block", seed=7) == held  # no draw: the seed does not move it
    rand = validation_items(ids, sources, 0.2, "random", seed=0)
    assert len(rand) == 3 and rand != validation_items(ids, sources, 0.2, "random", seed=1)
    # a share too small for every source: the last item of the largest
    assert [ids[i] for i in validation_items(ids[:3], ["a"] * 3, 0.1, "block", 0)] == ["a_009"]
    with pytest.raises(InputError, match="too few"):
        validation_items(["x"], ["a"], 0.5, "block", 0)


def test_fit_init_keeps_the_starting_weights_unless_an_epoch_beats_them(two_stores, tmp_path):
    """With validation, a fine-tuning run scores its starting weights as epoch 0, and only a last epoch
    with a higher validation IoU replaces them: training that cannot change the network (a rate too
    small to move a float32 weight, BatchNorm's statistics frozen) leaves the init's weights."""
    root, stores = two_stores
    a = load_checkpoint(root / "a.pt")
    args = ["fit", *stores, "--init", str(root / "a.pt"), "--schedule", "constant", "--weight-decay", "0",
            "--epochs", "2", "--val-fraction", "0.25", "--quiet"]
    r = CliRunner().invoke(app, [*args, "--lr", "1e-30", "--freeze-bn", "--out", str(tmp_path / "b.pt")])
    assert r.exit_code == 0, r.output
    b = load_checkpoint(tmp_path / "b.pt")
    assert b["epoch"] == 0 and b["best_epoch"] == 0 and b["history"][0]["init"] is True
    assert all(torch.equal(a["model"][k], b["model"][k]) for k in a["model"])  # running statistics included
    last = load_checkpoint(tmp_path / "b.last.pt")
    assert [row["val_iou"] for row in last["history"]] == [b["best_iou"]] * 3  # nothing moved: ties keep epoch 0
    assert b["config"]["val_split"] == "auto" and last["data"]["train_items_per_source"] == {stores[0]: 4, stores[1]: 2}  # 0.25 of 6 and of 2: 2 and 0
    # a real rate: the checkpoint is the last epoch where it scores higher than the start, else the start
    # (issue 72: not the best epoch, which on a few held-out frames was an early one)
    r = CliRunner().invoke(app, [*args, "--lr", "0.05", "--out", str(tmp_path / "c.pt")])
    assert r.exit_code == 0, r.output
    c, c_last = load_checkpoint(tmp_path / "c.pt"), load_checkpoint(tmp_path / "c.last.pt")
    ious = [row["val_iou"] for row in c_last["history"]]
    assert c["best_epoch"] == (2 if ious[2] > ious[0] else 0) and c["best_iou"] == max(ious[0], ious[2])


def test_fit_init_average_holds_the_mean_of_the_start_and_the_trained_weights(two_stores, tmp_path):
    """--average-init A: OUT holds A x the init's weights + (1 - A) x the trained ones (every float
    tensor, BatchNorm statistics included); OUT.last.pt the trained ones, and a resumed run averages
    with the same start. Without validation (--val-fraction 0) OUT is the last epoch."""
    root, stores = two_stores
    a = load_checkpoint(root / "a.pt")
    args = ["fit", stores[0], "--init", str(root / "a.pt"), "--lr", "0.05", "--epochs", "1", "--quiet",
            "--val-fraction", "0", "--average-init", "0.25", "--out", str(tmp_path / "b.pt")]
    r = CliRunner().invoke(app, args)
    assert r.exit_code == 0, r.output
    b, last = load_checkpoint(tmp_path / "b.pt"), load_checkpoint(tmp_path / "b.last.pt")
    assert b["config"]["val_fraction"] == 0 and b["epoch"] == 1 and b["average_init"] == 0.25
    floats = [k for k, v in a["model"].items() if v.is_floating_point()]
    assert any(not torch.equal(a["model"][k], last["model"][k]) for k in floats)  # training moved the weights
    for k in floats:
        torch.testing.assert_close(b["model"][k], 0.25 * a["model"][k] + 0.75 * last["model"][k])
    r = CliRunner().invoke(app, ["fit", stores[0], "--resume", str(tmp_path / "b.last.pt"), "--epochs", "2", "--quiet",
                                 "--out", str(tmp_path / "b.pt")])
    assert r.exit_code == 0, r.output
    b, last = load_checkpoint(tmp_path / "b.pt"), load_checkpoint(tmp_path / "b.last.pt")
    assert b["epoch"] == 2
    for k in floats:
        torch.testing.assert_close(b["model"][k], 0.25 * a["model"][k] + 0.75 * last["model"][k])
    r = CliRunner().invoke(app, [*args[:-4], "--average-init", "1", "--out", str(tmp_path / "c.pt")])
    assert r.exit_code != 0 and "average-init must be in [0, 1)" in str(r.exception)
    r = CliRunner().invoke(app, ["fit", stores[0], "--average-init", "0.5", "--epochs", "1", "--quiet", "--out",
                                 str(tmp_path / "d.pt")])  # nothing to average with: refused, not ignored
    assert r.exit_code != 0 and "starts from none" in str(r.exception)


def test_fit_init_of_a_resize_model_trains_at_its_working_size(tmp_path, camvid_half):
    """Fine-tuning a resize model on frames of another size keeps the model's working size (the
    frames' own would show it another scale); --size still wins."""
    from conftest import write_synthetic_dataset

    big = PRESETS["camvid"].for_image_size((160, 120))
    small = [str(p) for p in write_synthetic_dataset(tmp_path / "small", PRESETS["camvid"].for_image_size((96, 72)), n=2)]
    frames = [str(p) for p in write_synthetic_dataset(tmp_path / "big", big, n=2)]
    fit(TrainConfig(baseline="resize", images=small[0], labels=small[1], label_format="camvid", out=str(tmp_path / "a.pt"),
                    base_width=4, epochs=1, batch_size=2, val_fraction=0, progress=False, device="cpu"))
    assert load_checkpoint(tmp_path / "a.pt")["data"]["input_size"] == [96, 72]
    base = ["fit", "--baseline", "resize", "--images", frames[0], "--labels", frames[1], "--label-format", "camvid",
            "--init", str(tmp_path / "a.pt"), "--epochs", "1", "--val-fraction", "0", "--quiet"]
    r = CliRunner().invoke(app, [*base, "--out", str(tmp_path / "b.pt")])
    assert r.exit_code == 0, r.output
    assert load_checkpoint(tmp_path / "b.pt")["data"]["input_size"] == [96, 72]
    r = CliRunner().invoke(app, [*base, "--size", "128x96", "--out", str(tmp_path / "c.pt")])
    assert r.exit_code == 0, r.output
    assert load_checkpoint(tmp_path / "c.pt")["data"]["input_size"] == [128, 96]


@pytest.mark.parametrize("extra, needle", [(["--model", "segnet-narrow"], "checkpoint is a 'resfpn'"),
                                           (["--width", "8"], "checkpoint has width 4"),
                                           (["--vp-channel"], "input channels"),
                                           (["--baseline", "resize"], "mode 'virtual'")])
def test_fit_init_refuses_another_network_or_mode(two_stores, tmp_path, extra, needle):
    root, stores = two_stores
    r = CliRunner().invoke(app, ["fit", stores[1], "--init", str(root / "a.pt"), "--epochs", "1", "--out",
                                 str(tmp_path / "c.pt"), "--quiet", *extra])
    assert r.exit_code != 0 and isinstance(r.exception, InputError) and needle in str(r.exception)
    assert not (tmp_path / "c.pt").exists()


def test_study_train_balance_is_a_training_setting(tmp_path, camvid_half):
    """``train: {balance: datasets}`` is allowed in a study and reaches its training settings (so
    the models' keys); the default 'items' leaves the settings, and so the keys of studies written
    before the setting existed, as they were."""
    import yaml

    from conftest import write_synthetic_dataset
    from vcprep.camera import camera_to_yaml
    from vctrain.study import load_study, training_settings

    images, labels = write_synthetic_dataset(tmp_path / "a", camvid_half, n=2)
    (tmp_path / "cam.yaml").write_text(camera_to_yaml(camvid_half))
    split = {"images": str(images), "labels": str(labels)}
    d = {"datasets": [{"name": n, "camera": str(tmp_path / "cam.yaml"), "label_format": "camvid", "train": split,
                       "test": split} for n in ("a", "b")], "train": {"epochs": 1}}
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(d))
    assert "balance" not in training_settings(load_study(path))
    d["train"]["balance"] = "datasets"
    path.write_text(yaml.safe_dump(d))
    assert training_settings(load_study(path))["balance"] == "datasets"
    d["train"]["balance"] = "cameras"
    path.write_text(yaml.safe_dump(d))
    with pytest.raises(InputError):  # resolved like vctrain fit's: refused before any store is built
        training_settings(load_study(path))


def test_condition_average_trains_nothing_and_averages_within_and_resize(tmp_path):
    """Condition average (issue 44): the run's within and resize models, found trained, their
    probabilities averaged in the evaluated camera's pixels; no model of its own."""
    import json

    from conftest import run_cli
    from studies import _mixed_study, _rows
    from vcprep.store import Store
    from vctrain.predict import Predictor
    from vctrain.study.conditions import AveragePredictor

    study, out = _mixed_study(tmp_path / "data"), tmp_path / "out"
    first = run_cli("crossval", study, "--out", out, "--conditions", "within,resize", "--heldout", "kitti", prog="vctrain")
    assert first.returncode == 0, first.stderr
    trained = {c: (out / "runs" / "kitti" / c / "train.json").read_text() for c in ("within", "resize")}
    proc = run_cli("crossval", study, "--out", out, "--conditions", "within,resize,average", "--heldout", "kitti",
                   prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert "training on" not in proc.stderr  # both models found trained: average trains none
    assert {c: (out / "runs" / "kitti" / c / "train.json").read_text() for c in trained} == trained
    run_dir = out / "runs" / "kitti" / "average"
    assert not (run_dir / "model.pt").exists()
    row = json.loads((run_dir / "result.json").read_text())
    assert row["averaged"] == ["within", "resize"] and row["test_items"] == 2
    assert [r["condition"] for r in _rows(out)] == ["within", "resize", "average"]
    store = Store.open(out / "stores" / "kitti" / "test" / "within")
    rec = next(iter(store))
    w, r = (Predictor(out / "runs" / "kitti" / c / "model.pt", device="cpu") for c in ("within", "resize"))
    got = AveragePredictor([w, r]).store_item(store, rec)
    assert np.allclose(got, (w.store_item(store, rec) + r.store_item(store, rec)) / 2)
    assert got.shape == (rec["size"][1], rec["size"][0])


def _resize_and(condition: str, tmp_path: Path) -> tuple[Path, Path]:
    """A mixed study's kitti fold with conditions resize and ``condition`` (each its own model);
    returns (study output, the condition's run folder)."""
    from conftest import run_cli
    from studies import _mixed_study

    study, out = _mixed_study(tmp_path / "data"), tmp_path / "out"
    proc = run_cli("crossval", study, "--out", out, "--conditions", f"resize,{condition}", "--heldout", "kitti",
                   prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count("training on") == 2  # its own model, not the resize model's
    return out, out / "runs" / "kitti" / condition


def test_condition_resize_vp_is_resize_with_each_frames_own_vp_channel(tmp_path):
    """Condition resize-vp (issue 44): the resize baseline's frames read as they are plus a 4th input,
    the VP proximity map of each frame's own estimated VP (the within stores' records); its own
    model key (never the resize model's), and scored with those VPs: moving a record's VP changes
    its probabilities, and the result is the one recomputed from the model and the records."""
    import json

    from conftest import run_cli
    from vcprep.labels import decode_label, get_label_format
    from vcprep.io import read_image
    from vcprep.store import Store
    from vctrain.metrics import RoadMetrics
    from vctrain.predict import Predictor

    out, run_dir = _resize_and("resize-vp", tmp_path)
    ck = load_checkpoint(run_dir / "model.pt")
    assert ck["data"]["mode"] == "resize" and ck["data"]["vp_channel"] is True
    assert ck["model_args"]["in_channels"] == 4
    assert load_checkpoint(out / "runs" / "kitti" / "resize" / "model.pt")["model_args"]["in_channels"] == 3
    model = Predictor(run_dir / "model.pt", device="cpu")
    store = Store.open(out / "stores" / "kitti" / "test" / "within")
    m = RoadMetrics()
    for rec in store:
        assert rec.get("vp") is not None
        prob = model.store_item(store, rec)
        moved = model.store_item(store, {**rec, "vp": [rec["vp"][0], rec["vp"][1] + 40]})
        assert not np.allclose(prob, moved)
        label = decode_label(read_image(rec["label_source"], label=True).array, get_label_format(rec["label_format"]),
                             rec["label_source"])
        m.add(prob >= 0.5, label)
    row = json.loads((run_dir / "result.json").read_text())
    assert row["iou"] == pytest.approx(m.result()["iou"], abs=1e-9)
    # predict without the camera: one line naming the model, the need and the fix (no traceback)
    from conftest import assert_one_error_line

    frame = Path(rec["source"])
    bad = run_cli("predict", run_dir / "model.pt", frame, "--out", tmp_path / "p", "--device", "cpu", prog="vctrain")
    assert bad.returncode != 0
    assert_one_error_line(bad, "vanishing point", "--camera")


def test_condition_mixed_trains_one_network_on_both_views_and_averages_them(tmp_path):
    """Condition mixed (issue 53): ONE model trained on both views of every training frame (the
    within store item at the store's size, the source resized at the resize twin's size; every batch
    of one view, the steps of one view's run), scored as the mean of its two views' probabilities in
    the evaluated camera's pixels; frames, video and export refuse it in one line."""
    import json

    from conftest import run_cli
    from vcprep.store import Store
    from vctrain.training import MixedViews, view_batches
    from vctrain.predict import Predictor
    from vctrain.predict.predictor import refuse_mixed

    out, run_dir = _resize_and("mixed", tmp_path)
    ck = load_checkpoint(run_dir / "model.pt")
    rz = load_checkpoint(out / "runs" / "kitti" / "resize" / "model.pt")
    data = ck["data"]
    assert data["mode"] == "mixed"
    assert data["resize_size"] == rz["data"]["input_size"]  # the resize view: the twin's size
    n = data["views"][0]
    assert data["views"] == [n, n] and data["train_items"] == 2 * n
    assert [Path(p).parts[-3:] for p in ck["config"]["stores"]] == [("camvid", "train", "within")]
    assert tuple(data["input_size"]) == Store.open(ck["config"]["stores"][0]).store_size  # the virtual view
    assert ck["step"] == rz["step"]  # the same optimiser steps as the one-view twin
    # scored: the mean of the virtual view (back-projected) and the resized view, in the camera's pixels
    model = Predictor(run_dir / "model.pt", device="cpu")
    store = Store.open(out / "stores" / "kitti" / "test" / "within")
    rec = next(iter(store))
    got = model.store_item(store, rec)
    both = (model._virtual_item(store, rec), model._resized_item(rec, tuple(data["resize_size"])))
    assert np.allclose(got, (both[0] + both[1]) / 2) and not np.allclose(both[0], both[1])
    assert got.shape == (rec["size"][1], rec["size"][0])
    # batches hold one view each, in the order's order
    a, b = (RoadDataset([Sample(f"{v}{i}", Path("x"), None) for i in range(5)], (64, 32)) for v in "ab")
    mixed = MixedViews(a, b)
    batches = view_batches(mixed, [0, 5, 1, 6, 7, 2, 8, 9, 3, 4], 2)
    assert batches == [[0, 1], [5, 6], [7, 8], [2, 3], [4], [9]]
    assert all({mixed.view(i) for i in bt} in ({0}, {1}) for bt in batches)
    assert sorted(i for bt in batches for i in bt) == list(range(10))
    with pytest.raises(InputError, match="mixed-view"):
        refuse_mixed(model)
    from conftest import assert_one_error_line

    camera = tmp_path / "data" / "kitti.yaml"
    bad = run_cli("predict", run_dir / "model.pt", rec["source"], "--camera", camera, "--out", tmp_path / "p",
                  "--device", "cpu", prog="vctrain")
    assert bad.returncode != 0
    assert_one_error_line(bad, "mixed-view", "--store")


def test_ray_channels_are_each_pixels_angles_from_the_vp_and_focal_length(tmp_path):
    """Ray-angle channels (issue 53, CAM-Convs): channel 3 = atan((x - x_vp) / f_x), channel 4 =
    atan((y - y_vp) / f_y) in working pixels. Oracle: a 2x zoom about the VP is a camera of twice the
    focal length, so the augmented item's angles equal the formula with f scaled by the zoom; a
    flip mirrors the angle beside the VP."""
    import math

    from vctrain.training import ray_angles

    img = (np.arange(40 * 80 * 3, dtype=np.uint32).reshape(40, 80, 3) % 251).astype(np.uint8)
    write_png(tmp_path / "a.png", img)
    write_png(tmp_path / "a_lab.png", np.ones((40, 80), np.uint8))
    s = Sample("a", tmp_path / "a.png", tmp_path / "a_lab.png", None, vp=(30.0, 10.0), focal=(100.0, 90.0))
    ds = RoadDataset([s], (160, 80), ray_channels=True)  # the working size: 2x the image
    x, _ = ds[0]
    assert x.shape == (5, 80, 160)
    # working pixels (pixel centres scaled: (v + 0.5) * 2 - 0.5): VP (60.5, 20.5), focal (200, 180)
    assert float(x[3, 7, 60]) == pytest.approx(math.atan(-0.5 / 200), abs=1e-6)
    assert float(x[4, 20, 3]) == pytest.approx(math.atan(-0.5 / 180), abs=1e-6)
    assert float(x[3, 0, 160 - 1]) == pytest.approx(math.atan(98.5 / 200), abs=1e-5)
    assert float(x[4, 79, 0]) == pytest.approx(math.atan(58.5 / 180), abs=1e-5)
    assert np.allclose(ray_angles((160, 80), (60.5, 20.5), (200.0, 180.0)), x[3:].numpy(), atol=1e-6)
    # a zoom about the VP (scale augmentation) is a longer focal length: the angles follow it
    torch.manual_seed(0)
    aug = RoadDataset([s], (160, 80), ray_channels=True, scale_aug=1.0, hflip=True)
    for _ in range(6):
        torch.manual_seed(_)
        xa, _y = aug[0]
        torch.manual_seed(_)
        img_w, lab_w, vp_w, zoom = aug._affine(*aug.item(0))
        flipped = not np.allclose(xa[3].numpy(), ray_angles((160, 80), vp_w, (200 * zoom, 180 * zoom))[0], atol=1e-5)
        vp_x = 160 - 1 - vp_w[0] if flipped else vp_w[0]
        want = ray_angles((160, 80), (vp_x, vp_w[1]), (200 * zoom, 180 * zoom))
        assert np.allclose(xa[3:].numpy(), want, atol=1e-5)
    with pytest.raises(InputError, match="ray channels"):
        RoadDataset([Sample("a", tmp_path / "a.png", tmp_path / "a_lab.png", None, vp=(30.0, 10.0))], (80, 40),
                    ray_channels=True).item(0)


def test_condition_resize_rays_trains_on_each_frames_camera_and_vp(tmp_path):
    """Condition resize-rays (issue 53): the resize twin with two more inputs (lite0fpn's stem gives
    them zero weight at the start: test_efficientnet); scored with each record's own VP and focal
    length: a longer focal length in the record changes its probabilities; frames, video and export
    refuse the model in one line."""
    import json

    from conftest import assert_one_error_line, run_cli
    from vcprep.store import Store
    from vctrain.predict import Predictor
    from vctrain.predict.predictor import refuse_mixed

    out, run_dir = _resize_and("resize-rays", tmp_path)
    ck = load_checkpoint(run_dir / "model.pt")
    assert ck["data"]["mode"] == "resize" and ck["data"]["ray_channels"] is True
    assert ck["model_args"]["in_channels"] == 5
    model = Predictor(run_dir / "model.pt", device="cpu")
    store = Store.open(out / "stores" / "kitti" / "test" / "within")
    rec = next(iter(store))
    cp = rec["camera_params"]
    longer = {**rec, "camera_params": {**cp, "fx": 3 * cp["fx"], "fy": 3 * cp["fy"]}}
    assert not np.allclose(model.store_item(store, rec), model.store_item(store, longer))
    assert json.loads((run_dir / "result.json").read_text())["test_items"] == 2
    with pytest.raises(InputError, match="ray-channel"):
        refuse_mixed(model)
    bad = run_cli("predict", run_dir / "model.pt", rec["source"], "--camera",
                  tmp_path / "data" / "kitti.yaml", "--out", tmp_path / "p", "--device", "cpu", prog="vctrain")
    assert bad.returncode != 0
    assert_one_error_line(bad, "ray-channel", "--store")


def test_warp_into_a_models_virtual_camera_to_fine_tune_it(two_stores, tmp_path):
    """`vcprep warp --virtual MODEL.pt` (or --virtual STORE) warps new frames into the virtual camera
    and scale the model was trained in, so `vctrain fit NEW --init MODEL.pt` trains in its domain;
    a resize model, or a file that is no vctrain checkpoint, is refused in one line.

    The warps run `vcprep warp`'s entry point in this process (conftest.run_here: its own argv,
    stdout and stderr apart, the exit status), one job: a new interpreter importing torch to read the
    model cost ~2 s each, and nothing here is about processes or pools."""
    from conftest import run_here
    from vcprep.store import Store
    from vcprep.store.trained import trained_virtual

    root, stores = two_stores
    trained = load_checkpoint(root / "a.pt")["data"]["store_params"]
    cam = PRESETS["camvid"].resized(0.1)
    cam_file = tmp_path / "cam.yaml"
    cam_file.write_text(__import__("yaml").safe_dump(cam.to_dict(), sort_keys=False))
    src = root / "src1"

    def run_cli(*args):  # vcprep, here, -j 1
        return run_here(*args, "-j", "1")

    proc = run_cli("warp", "--camera", cam_file, "--images", src / "images", "--labels", src / "labels",
                   "--label-format", FMT, "--virtual", root / "a.pt", "--within", "none", "--out", tmp_path / "new-a", "-q")
    assert proc.returncode == 0, proc.stderr
    new = Store.open(tmp_path / "new-a").params
    assert {k: new[k] for k in ("virtual", "scale", "store_size")} == \
        {k: trained[k] for k in ("virtual", "scale", "store_size")}
    virt, scale = trained_virtual(stores[0])  # the model's training store says the same
    assert virt.to_dict() == trained["virtual"] and scale == trained["scale"]
    # without --virtual the design from the camera: another virtual camera than the model's
    proc = run_cli("warp", "--camera", cam_file, "--images", src / "images", "--out", tmp_path / "design", "-q",
                   "--within", "none")
    assert proc.returncode == 0 and Store.open(tmp_path / "design").params["virtual"] != trained["virtual"]
    r = CliRunner().invoke(app, ["fit", str(tmp_path / "new-a"), "--init", str(root / "a.pt"), "--epochs", "1",
                                 "--out", str(tmp_path / "b.pt"), "--quiet"])
    assert r.exit_code == 0, r.output
    assert load_checkpoint(tmp_path / "b.pt")["data"]["store_params"]["virtual"] == trained["virtual"]
    resize = load_checkpoint(root / "a.pt")
    resize["data"] = {**resize["data"], "mode": "resize", "store_params": None}
    torch.save(resize, tmp_path / "resize.pt")
    torch.save({"weights": 1}, tmp_path / "other.pt")
    proc = run_cli("warp", "--camera", cam_file, "--images", src / "images", "--virtual", tmp_path / "resize.pt",
                   "--out", tmp_path / "x", "-q")
    assert proc.returncode == 1 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert "a resize model has no virtual camera" in proc.stderr and "--baseline resize" in proc.stderr
    assert not (tmp_path / "x" / "store.json").exists()
    for bad, says in (("other.pt", "not a vctrain checkpoint"), ("gone.pt", "no such model file")):
        with pytest.raises(InputError, match=says):
            trained_virtual(tmp_path / bad)
