"""``shading_aug``: a smooth per-channel colour gain over the image, the lens shading of cheap cameras
(LUMS's bottom corners are tinted green and magenta; issue 34, item 5)."""
from __future__ import annotations

import numpy as np
import pytest
import torch
import yaml

from vcprep.errors import InputError
from vcprep.io import write_png
from vctrain.training import RoadDataset, Sample, TrainConfig, resolve_recipe

def test_shading_aug_is_a_recipe_setting_checked_like_the_others():
    assert resolve_recipe(TrainConfig(recipe="paper")).shading_aug == 0.0
    assert resolve_recipe(TrainConfig(recipe="cpu")).shading_aug == 0.0
    with pytest.raises(InputError, match="shading-aug"):
        resolve_recipe(TrainConfig(recipe="cpu", shading_aug=-0.1))


def test_study_shading_aug_reaches_the_keys_only_when_set(tmp_path, camvid_half):
    """At the value that trains as before it stays out of a study's training settings (the keys of
    studies from before the setting are unchanged); any other value is in them."""
    from conftest import write_synthetic_dataset
    from vcprep.camera import camera_to_yaml
    from vctrain.study import load_study, training_settings

    images, labels = write_synthetic_dataset(tmp_path / "a", camvid_half, n=2)
    (tmp_path / "cam.yaml").write_text(camera_to_yaml(camvid_half))
    split = {"images": str(images), "labels": str(labels)}
    d = {"datasets": [{"name": n, "camera": str(tmp_path / "cam.yaml"), "label_format": "camvid", "train": split,
                       "test": split} for n in ("a", "b")], "train": {"epochs": 1, "shading_aug": 0.0}}
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(d))
    assert "shading_aug" not in training_settings(load_study(path))
    d["train"]["shading_aug"] = 0.5
    path.write_text(yaml.safe_dump(d))
    assert training_settings(load_study(path))["shading_aug"] == 0.5


def test_shading_is_a_smooth_bounded_colour_gain_on_half_the_items(tmp_path):
    """``shading_aug`` a: half the draws leave the item as it is; the others multiply each colour
    channel by a smooth field within [exp(-a), exp(a)] that differs between channels; the label
    never changes."""
    w, h, a = 96, 64, 0.4
    img = np.full((h, w, 3), 128, np.uint8)
    lab = (np.arange(h)[:, None] > 30).repeat(w, 1).astype(np.uint8)
    write_png(tmp_path / "i.png", img)
    write_png(tmp_path / "l.png", lab)
    ds = RoadDataset([Sample("a", tmp_path / "i.png", tmp_path / "l.png")], (w, h), shading_aug=a)
    plain = RoadDataset([Sample("a", tmp_path / "i.png", tmp_path / "l.png")], (w, h))[0][0].numpy()
    torch.manual_seed(0)
    unchanged, colour = 0, []
    for _ in range(100):
        x, y = ds[0]
        assert np.array_equal(y.numpy(), lab)
        x = x.numpy()
        if np.array_equal(x, plain):
            unchanged += 1
            continue
        gain = (x + 1) / (plain + 1)  # per channel and pixel
        assert gain.min() >= np.exp(-a) - 1e-3 and gain.max() <= np.exp(a) + 1e-3
        assert np.abs(np.diff(np.log(gain), axis=2)).max() < 2 * a / 8  # smooth: no jump between neighbours
        colour.append(np.abs(np.log(gain[0]) - np.log(gain[2])).max())
    assert 35 <= unchanged <= 65
    assert np.median(colour) > a / 4  # the channels differ: a colour cast, not only brightness
