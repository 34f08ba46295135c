"""Training on several stores: per-dataset balance of an epoch's draws (vctrain.data.epoch_order,
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
from vctrain.checkpoint import load_checkpoint
from vctrain.cli import app
from vctrain.config import TrainConfig
from vctrain.data import RoadDataset, Sample, epoch_order
from vctrain.train import _epoch_loader, fit

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
    # 'items' (the default) visits every item once: the large store holds 96 % of the epoch
    items = _drawn(ds, TrainConfig(seed=3), 0)
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


def test_condition_resize_vp_is_resize_with_each_frames_own_vp_channel(tmp_path):
    """Condition resize-vp (issue 44): the resize baseline's frames read as they are plus a 4th input,
    the VP proximity map of each frame's own estimated VP (the within stores' records); its own
    model key (never the resize model's), and scored with those VPs: moving a record's VP changes
    its probabilities, and the result is the one recomputed from the model and the records."""
    import json

    from conftest import run_cli
    from studies import _mixed_study
    from vcprep.labels import decode_label, get_label_format
    from vcprep.io import read_image
    from vcprep.store import Store
    from vctrain.metrics import RoadMetrics
    from vctrain.predict import Predictor

    study, out = _mixed_study(tmp_path / "data"), tmp_path / "out"
    proc = run_cli("crossval", study, "--out", out, "--conditions", "resize,resize-vp", "--heldout", "kitti",
                   prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count("training on") == 2  # its own model, not the resize model's
    run_dir = out / "runs" / "kitti" / "resize-vp"
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
