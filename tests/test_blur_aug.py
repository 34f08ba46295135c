"""``blur_aug`` (resolution augmentation: a wide or low-resolution camera warped into the virtual camera
is magnified, so its detail is that of a camera with fewer pixels per degree) and the issue-44 training
settings' place in a study's keys."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
import torch
import yaml

from vcprep.errors import InputError
from vcprep.io import write_png
from vctrain.config import TrainConfig
from vctrain.data import RoadDataset, Sample
from vctrain.train import resolve_recipe


def _item(tmp_path, w=96, h=64):
    img = (np.random.default_rng(0).random((h, w, 3)) * 255).astype(np.uint8)
    lab = (np.arange(h)[:, None] > 30).repeat(w, 1).astype(np.uint8)
    write_png(tmp_path / "i.png", img)
    write_png(tmp_path / "l.png", lab)
    return Sample("a", tmp_path / "i.png", tmp_path / "l.png"), img, lab


def test_blur_aug_is_a_recipe_setting_checked_like_the_others():
    assert resolve_recipe(TrainConfig(recipe="paper")).blur_aug == 0.0
    assert resolve_recipe(TrainConfig(recipe="cpu")).blur_aug == 0.0
    with pytest.raises(InputError, match="blur-aug"):
        resolve_recipe(TrainConfig(recipe="cpu", blur_aug=-1.0))


def test_blur_is_a_down_and_up_sampling_by_at_most_one_plus_a_on_half_the_items(tmp_path):
    """Half the draws leave the image as it is; each other one is exactly the image down-sampled
    (area) to one of the sizes w / s for s in [1, 1 + a] and up-sampled (bilinear) back (an
    independent search over the sizes finds it); the label never changes."""
    sample, img, lab = _item(tmp_path)
    h, w = img.shape[:2]
    a = 1.5
    ds = RoadDataset([sample], (w, h), blur_aug=a)
    plain = RoadDataset([sample], (w, h))[0][0].numpy()
    candidates = {}
    for sw, sh in ((sw, sh) for sw in range(math.floor(w / (1 + a)), w + 1)
                   for sh in range(math.floor(h / (1 + a)), h + 1) if (sw, sh) != (w, h)):
        up = cv2.resize(cv2.resize(img, (sw, sh), interpolation=cv2.INTER_AREA), (w, h), interpolation=cv2.INTER_LINEAR)
        candidates[(sw, sh)] = up.astype(np.float32) / 255 * 2 - 1
    torch.manual_seed(1)
    unchanged, factors = 0, []
    for _ in range(60):
        x, y = ds[0]
        assert np.array_equal(y.numpy(), lab)
        x = x.numpy()
        if np.array_equal(x, plain):
            unchanged += 1
            continue
        hits = [k for k, c in candidates.items() if np.allclose(x, c.transpose(2, 0, 1), atol=1e-6)]
        assert hits, "a changed draw is no down-and-up sampling of the image"
        factors.append(w / hits[0][0])
    assert 15 <= unchanged <= 45
    assert min(factors) >= 1.0 and max(factors) <= (1 + a) * 1.02 and max(factors) > 1.6  # the range is used


@pytest.mark.parametrize("key, on", [("blur_aug", 1.5), ("seen_only", True)])
def test_issue44_settings_reach_the_keys_only_when_set(tmp_path, camvid_half, key, on):
    """At the value that trains as before a setting stays out of a study's training settings (the
    keys, and so the models, of studies from before it are unchanged); any other value is in them."""
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
    before = training_settings(load_study(path))
    assert key not in before
    d["train"][key] = on
    path.write_text(yaml.safe_dump(d))
    assert training_settings(load_study(path))[key] == on
