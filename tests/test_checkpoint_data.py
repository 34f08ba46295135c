"""vctrain/training/checkpoint_data.py: the checkpoint's ``data`` section, typed and read in one place."""
from __future__ import annotations

from pathlib import Path

import pytest

from vctrain.training import CheckpointData, load_checkpoint

ROOT = Path(__file__).resolve().parents[1]
VIRTUAL = {"mode": "virtual", "store_params": {"scale": 0.5, "store_size": [110, 56], "virtual": {"fx": 2262},
                                               "virtual_scaled": {"fx": 1131, "cx": 54.5}},
           "completion": "projective", "vp_channel": False, "greyscale": 0.0, "input_size": [110, 56],
           "crop_size": [66, 34], "vp_status": ["accepted", "fallback"], "vp_rule": {"min_support": 7},
           "source_magnification": 1.3, "train_items": 8, "val_items": 3, "held_out": "a seeded 10%"}


def test_smoke_types_and_shapes():
    d = CheckpointData.from_dict(VIRTUAL)
    assert d.mode == "virtual" and d.virtual and d.input_size == (110, 56) and d.crop_size == (66, 34)
    assert d.store_size == (110, 56) and d.virtual_scaled["cx"] == 54.5 and d.vp_status == ("accepted", "fallback")
    assert d.source_magnification == 1.3 and d.train_items == 8 and d.extra == {"held_out": "a seeded 10%"}
    with pytest.raises(AttributeError):
        d.mode = "resize"  # frozen


def test_round_trip_gives_the_section_back_as_read():
    assert CheckpointData.from_dict(VIRTUAL).to_dict() == VIRTUAL
    assert list(CheckpointData.from_dict(VIRTUAL).to_dict()) == list(VIRTUAL)  # (its keys' order too)


def test_older_checkpoints_missing_keys_take_the_defaults():
    """A model trained before ``source_magnification``, ``ray_channels``, ``vp_rule`` were recorded."""
    old = {"mode": "resize", "input_size": [64, 48], "store_params": None}
    d = CheckpointData.from_dict(old)
    assert (d.source_magnification, d.ray_channels, d.vp_rule, d.vp_status, d.completion) == (None, False, None, (), "none")
    assert not d.virtual and d.store_size is None and d.to_dict() == old
    assert CheckpointData.from_dict(None) == CheckpointData.from_dict({}) == CheckpointData()


@pytest.mark.parametrize("model", sorted((ROOT / "models").glob("*/*.pt")), ids=lambda p: p.parent.name)
def test_the_committed_models_read_unchanged(model):
    data = load_checkpoint(model)["data"]
    d = CheckpointData.from_dict(data)
    assert d.to_dict() == data and d.input_size == tuple(data["input_size"]) and d.mode == data["mode"]
