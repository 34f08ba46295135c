"""``height_aug``: a training item seen from a higher camera, so the near field of a camera lower than
the training cameras lands on rows the network has seen real road on (issue 34, item 5)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
import yaml

from vcprep.camera import PRESETS
from vcprep.errors import InputError
from vcprep.imageio import write_png
from vcprep.synthetic import RoadScene, render_road
from vctrain.config import TrainConfig
from vctrain.data import RoadDataset, Sample
from vctrain.train import resolve_recipe

SCENE = RoadScene(width=7.0, texture_seed=4)


def _virtual(height: float):
    """A level virtual camera (220x112, horizon row 55.5) at ``height`` metres."""
    return dataclasses.replace(PRESETS["virtual"].resized(0.04), height=height)


def test_the_stretch_is_the_same_road_seen_from_a_higher_camera(tmp_path):
    """Oracle: the road rendered from a level camera at 1.0 m, stretched by t = 1.6 about the VP
    row, is the same road rendered from 1.6 m (a ground point at depth Z is at y - y_vp = f h / Z)."""
    low, high = _virtual(1.0), _virtual(1.6)
    img, lab = render_road(low, SCENE)
    ref_img, ref_lab = render_road(high, SCENE)
    w, h = low.size
    ds = RoadDataset([], (w, h))
    out_img, out_lab, vp = ds._affine(img, lab, (low.cx, low.cy), t=1.6)
    assert vp[1] == pytest.approx(low.cy) and vp[0] == pytest.approx(low.cx)
    rows = slice(int(low.cy) + 6, h)  # the ground, clear of the horizon's haze
    agree = (out_lab[rows] == ref_lab[rows]).mean()
    assert agree > 0.98
    diff = np.abs(out_img[rows].astype(float) - ref_img[rows].astype(float)).mean()
    unstretched = np.abs(img[rows].astype(float) - ref_img[rows].astype(float)).mean()
    assert diff < 0.25 * unstretched  # the same scene, not merely a similar one
    assert (lab[rows] == ref_lab[rows]).mean() < agree - 0.03


def _marked_item(tmp_path, valid: bool) -> tuple[Sample, int]:
    """An item of a 120x80 store, VP row 20, real down to row 50 (its valid map), label 1 on row 50 only."""
    w, h, b = 120, 80, 50
    img = np.full((h, w, 3), 90, np.uint8)
    lab = np.zeros((h, w), np.uint8)
    lab[b] = 1
    v = np.zeros((h, w), np.uint8)
    v[: b + 1, 10:110] = 1
    write_png(tmp_path / "i.png", img)
    write_png(tmp_path / "l.png", lab)
    write_png(tmp_path / "v.png", v)
    return Sample("a", tmp_path / "i.png", tmp_path / "l.png", None, (60.0, 20.0), "s",
                  tmp_path / "v.png" if valid else None), b


def _lowest_marked_rows(ds: RoadDataset, n: int) -> list[int]:
    torch.manual_seed(0)
    out = []
    for _ in range(n):
        _, y = ds[0]
        out.append(int(np.nonzero((y.numpy() == 1).any(axis=1))[0].max()))
    return out


def test_real_rows_are_stretched_down_to_the_last_row_and_no_further(tmp_path):
    sample, b = _marked_item(tmp_path, valid=True)
    ds = RoadDataset([sample], (120, 80), height_aug=1.0)
    assert ds.real_bottom(0) == b
    low = _lowest_marked_rows(ds, 200)
    assert min(low) >= b and max(low) <= 79
    assert max(low) >= 76  # T takes row 50 to the last row: draws reach it
    assert np.median(low) > b + 5  # every draw stretches (p = 1): most move the row well down
    half = _lowest_marked_rows(RoadDataset([sample], (120, 80), height_aug=0.5), 200)
    assert 0.35 < np.mean(np.array(half) == b) < 0.65  # p = 0.5: about half the draws leave it


def test_items_real_to_the_last_row_and_the_default_are_left_as_they_are(tmp_path):
    sample, b = _marked_item(tmp_path, valid=False)  # no valid map: a resize item, real everywhere
    ds = RoadDataset([sample], (120, 80), height_aug=1.0)
    assert ds.real_bottom(0) == 79
    assert set(_lowest_marked_rows(ds, 50)) == {b}
    sample, b = _marked_item(tmp_path, valid=True)
    assert set(_lowest_marked_rows(RoadDataset([sample], (120, 80)), 20)) == {b}


def test_height_aug_is_a_recipe_setting_checked_like_the_others(tmp_path):
    assert resolve_recipe(TrainConfig(recipe="paper")).height_aug == 0.0
    assert resolve_recipe(TrainConfig(recipe="cpu")).height_aug is not None
    with pytest.raises(InputError, match="height-aug"):
        resolve_recipe(TrainConfig(recipe="cpu", height_aug=1.5))


def test_study_height_aug_reaches_the_keys_only_when_set(tmp_path, camvid_half):
    """At the value that trains as before it stays out of a study's training settings (the keys of
    studies from before the setting are unchanged); any other value is in them."""
    from conftest import write_synthetic_dataset
    from vcprep.camera import camera_to_yaml
    from vctrain.study import load_study, training_settings

    images, labels = write_synthetic_dataset(tmp_path / "a", camvid_half, n=2)
    (tmp_path / "cam.yaml").write_text(camera_to_yaml(camvid_half))
    split = {"images": str(images), "labels": str(labels)}
    d = {"datasets": [{"name": n, "camera": str(tmp_path / "cam.yaml"), "label_format": "camvid", "train": split,
                       "test": split} for n in ("a", "b")], "train": {"epochs": 1, "height_aug": 0.0}}
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(d))
    assert "height_aug" not in training_settings(load_study(path))
    d["train"]["height_aug"] = 0.5
    path.write_text(yaml.safe_dump(d))
    assert training_settings(load_study(path))["height_aug"] == 0.5
