"""Completion (vcprep.warp.completion, paper §4.3): one remap for warp + completion, its ablations,
the edge cases of issue 4, and the `complete` / `warp --complete` / `figure completion` commands.

Oracle: synthetic road renders (vcprep.synthetic). The virtual camera rendered directly sees the
whole virtual view, so it tells how right a completion is outside the narrow camera's footprint.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from vcprep.store import WarpSettings, warp_dataset
from vcprep.vp import ItemPose
from vcprep.dataset import list_dataset
from vcprep.camera import PRESETS
from vcprep.warp import (LABEL_RIM, METHODS, TABLE_ARC, CompletionMaps, border_ignore, check_method, complete_maps,
                               completion_maps, exit_points_rectangle, label_exit_points, store_vp)
from vcprep.errors import InputError
from vcprep.warp import apply_homography, virt_H_src, virtual_at_scale, vp_from_pose
from vcprep.labels import LABEL_FORMATS
from vcprep.synthetic import RoadScene, render_road
from vcprep.warp import OUTSIDE, maps_for, warp_image, warp_label

from conftest import PAPER_STORE, EXAMPLES, run_here, assert_one_error_line, run_cli, write_synthetic_dataset

V8 = virtual_at_scale(PRESETS["virtual"], 0.125)  # 688 x 350
SCENE = RoadScene(offset=0.8, width=9.0, texture_seed=3)


def _setup(cam, pan=None, tilt=None, scene=SCENE):
    """Render through ``cam``, return (img, lab, H, vp_store) for the virtual camera at 1/8."""
    img, lab = render_road(cam, scene, pan=pan, tilt=tilt, supersample=1)
    H = virt_H_src(cam, V8, pan, tilt)
    vp = store_vp(H, vp_from_pose(cam, pan, tilt))
    return img, lab, H, vp


def _agreement(cam, pan=None, tilt=None):
    img, lab, H, vp = _setup(cam, pan, tilt)
    ref_img, ref_lab = render_road(V8, SCENE, supersample=1)
    out = {}
    for m in ("projective", "zero", "replicate"):
        maps = completion_maps(H, cam.size, V8.size, m, vp)
        wl = warp_label(lab, maps, maps.label_border)
        unc = maps.valid == 0
        out[m] = float((wl[unc] == ref_lab[unc]).mean())
    return out


# -- quality ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("name,pan,tilt", [("camvid", 4.0, 3.0), ("kitti", -3.0, 0.0), ("toronto2020", None, None)])
def test_projective_beats_zero_and_replicate(name, pan, tilt):
    cam = PRESETS[name] if name == "kitti" else PRESETS[name].for_image_size(
        (PRESETS[name].size[0] // 2, PRESETS[name].size[1] // 2))
    agree = _agreement(cam, pan, tilt)
    print(name, {k: round(v, 4) for k, v in agree.items()})
    assert agree["projective"] > agree["replicate"] > agree["zero"]
    assert agree["projective"] > 0.98


# -- smoke, identity, analytic ---------------------------------------------------------------------

def test_methods_shapes_and_borders(camvid_half):
    img, lab, H, vp = _setup(camvid_half)
    base = maps_for(H, camvid_half.size, V8.size)
    for m in METHODS:
        maps = completion_maps(H, camvid_half.size, V8.size, m, vp)
        assert isinstance(maps, CompletionMaps) and maps.method == m
        assert maps.map_x.shape == (350, 688) and maps.map_x.dtype == np.float32
        assert np.array_equal(maps.valid, base.valid)
        cov = base.valid == 1  # covered pixels are never touched
        assert np.array_equal(maps.map_x[cov], base.map_x[cov]) and np.array_equal(maps.map_y[cov], base.map_y[cov])
        filled = (maps.map_x[~cov] != OUTSIDE).all()
        assert filled == (m in ("projective", "replicate"))
        wl = warp_label(lab, maps, maps.label_border)
        assert set(np.unique(wl)) <= {0, 1, 255}
        if m == "none":
            assert (wl[~cov] == 255).all() and not warp_image(img, maps)[~cov].any()
        if m == "zero":
            assert (wl[~cov] == 0).all() and not warp_image(img, maps)[~cov].any()
        if m in ("projective", "replicate"):
            assert (wl != 255).all()
    assert completion_maps(H, camvid_half.size, V8.size, "projective", vp) is \
        completion_maps(H, camvid_half.size, V8.size, "projective", vp)  # cached
    with pytest.raises(InputError, match="unknown completion method"):
        check_method("mirror")


def test_clear_cache_builds_the_maps_afresh(camvid_half):
    """The public cache resets (a benchmark's cold start): after them the maps are built again (new
    objects, where without them the cached ones come back), equal to what was cached."""
    from vcprep.warp import completion, remap as warp

    img, _, H, vp = _setup(camvid_half)
    build = lambda: (maps_for(H, camvid_half.size, V8.size),  # noqa: E731
                     completion_maps(H, camvid_half.size, V8.size, "projective", vp))
    base, maps = build()
    again = build()
    assert again[0] is base and again[1] is maps  # cached
    warp.clear_cache()
    completion.clear_cache()
    base2, maps2 = build()
    assert base2 is not base and maps2 is not maps
    for a, b in ((base2.map_x, base.map_x), (maps2.map_x, maps.map_x), (maps2.map_y, maps.map_y)):
        assert np.array_equal(a, b)
    assert np.array_equal(warp_image(img, maps2), warp_image(img, maps))


def test_projective_rays_are_exact(camvid_half):
    """Every uncovered pixel samples a source-boundary point whose image lies on the segment from
    the VP to that pixel (H maps rays from the VP to rays from the VP), up to the fill table's
    angular step: at most TABLE_ARC / 2 px of arc at the farthest store pixel, so a boundary point
    at distance d is at most d * TABLE_ARC / (2 far) off the ray."""
    _, _, H, vp = _setup(camvid_half, pan=5.0, tilt=-2.0)
    w, h = camvid_half.size
    maps = completion_maps(H, (w, h), V8.size, "projective", vp)
    assert maps.vp_inside and maps.centre == pytest.approx(vp)
    vs, us = np.nonzero(maps.valid == 0)
    x, y = maps.map_x[vs, us].astype(np.float64), maps.map_y[vs, us].astype(np.float64)
    # on the source boundary (the angle table cuts the rectangle's corners by a fraction of a pixel)
    assert np.minimum.reduce([x, w - 1 - x, y, h - 1 - y]).max() < 0.3
    q = apply_homography(H, np.column_stack([x, y]))
    a = np.column_stack([us - vp[0], vs - vp[1]])
    b = q - np.array(vp)
    cross = (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]) / np.linalg.norm(a, axis=1)
    far = max(np.hypot(cx - vp[0], cy - vp[1]) for cx in (0, V8.size[0] - 1) for cy in (0, V8.size[1] - 1))
    bound = np.linalg.norm(b, axis=1) * TABLE_ARC / (2 * far) + 0.01  # + float32 maps
    assert (np.abs(cross) <= bound).all()
    assert np.abs(cross).max() > 0.02  # (the table's quantisation is visible: the bound is not vacuous)
    t = (a * b).sum(1) / (a * a).sum(1)
    assert (t > 0).all() and (t < 1 + 1e-6).all()  # between the VP and the pixel


def test_exit_points_rectangle_known_case():
    x, y = exit_points_rectangle(np.array([5.0, 5.0]), np.array([1.0, -1.0, 0.0, 1.0]),
                                 np.array([0.0, 0.0, 1.0, 1.0]), (11, 21))
    assert np.allclose(x, [10, 0, 5, 10]) and np.allclose(y, [5, 5, 20, 10])


def test_boundary_table_matches_rectangle(camvid_half):
    """The table path (used when labels cut the region) agrees with the exact rectangle path;
    a single ignore pixel in a corner forces the table path."""
    _, _, H, vp = _setup(camvid_half)
    w, h = camvid_half.size
    ign = np.zeros((h, w), bool)
    ign[0, 0] = True
    base = maps_for(H, (w, h), V8.size)
    exact = complete_maps(base, H, (w, h), "projective", vp)
    table = complete_maps(base, H, (w, h), "projective", vp, ign)
    unc = base.valid == 0
    d = np.hypot(exact.map_x - table.map_x, exact.map_y - table.map_y)[unc]
    assert np.percentile(d, 99) < 2.0 and d.max() < 4.0  # 1 px inset + interpolation between pixels


# -- edge cases ------------------------------------------------------------------------------------

def test_bonnet_and_border_ignore_are_not_smeared(camvid_half):
    img, lab, H, vp = _setup(camvid_half)
    h, w = lab.shape
    lab = lab.copy()
    img = img.copy()
    lab[-40:, 100:380] = 255      # bonnet touching the bottom border
    lab[:, :12] = 255             # rectification border down the left side
    lab[150:160, 200:210] = 255   # an interior ignore hole: not a boundary
    img[lab == 255] = (255, 0, 255)
    ign = border_ignore(lab)
    assert ign[-1, 200] and ign[100, 0] and not ign[155, 205]
    maps = completion_maps(H, (w, h), V8.size, "projective", vp, ign)
    wi, wl = warp_image(img, maps), warp_label(lab, maps, maps.label_border)
    unc, cov = maps.valid == 0, maps.valid == 1
    assert set(np.unique(wl)) <= {0, 1, 255}
    assert not (wl[unc] == 255).any()                       # completion never takes ignore
    bonnet_store = warp_label(lab, maps_for(H, (w, h), V8.size)) == 255
    assert (wl[bonnet_store & cov] == 255).all()            # the bonnet stays ignore
    magenta = (wi[..., 0] > 120) & (wi[..., 1] < 100) & (wi[..., 2] > 120)
    assert not magenta[unc].any()                           # bonnet colour not smeared outward
    # below the bonnet the road continues (label road straight below the VP)
    assert wl[-1, int(round(vp[0]))] == 1
    rmaps = completion_maps(H, (w, h), V8.size, "replicate", vp, ign)
    assert not (warp_label(lab, rmaps)[unc] == 255).any()


def test_vp_above_the_image_falls_back_and_says_so(camvid_half):
    tilt = 25.0  # pitched down so far that the road VP is above the top edge
    assert vp_from_pose(camvid_half, 0.0, tilt)[1] < 0
    img, lab, H, vp = _setup(camvid_half, 0.0, tilt)
    maps = completion_maps(H, camvid_half.size, V8.size, "projective", vp)
    assert not maps.vp_inside and "outside the covered region" in maps.note
    u, v = (int(round(c)) for c in maps.centre)
    assert maps.valid[v, u] == 1
    assert (maps.map_x != OUTSIDE).all() and (maps.map_x >= 0).all() and (maps.map_y <= camvid_half.size[1] - 1).all()
    assert (warp_label(lab, maps) != 255).all()
    # a VP far away (bad estimate) and one inside an ignore band: also defined
    for bad in [(-5000.0, -3000.0), (1e5, 10.0)]:
        m = completion_maps(H, camvid_half.size, V8.size, "projective", bad)
        assert not m.vp_inside and (m.map_x != OUTSIDE).all()


def test_vp_outside_is_recorded_in_the_store(tmp_path, camvid_half):
    images, labels = write_synthetic_dataset(tmp_path / "ds", camvid_half, n=1)
    jobs = list_dataset(images, labels, LABEL_FORMATS["camvid"])
    poses = {jobs[0].id: ItemPose((240.0, -40.0), "given")}  # VP above the image
    store, summary = warp_dataset(jobs, tmp_path / "st", WarpSettings(
        PRESETS["camvid"], PRESETS["virtual"], 0.125, LABEL_FORMATS["camvid"], completion="projective", poses=poses,
        progress=False))
    rec = store.get(jobs[0].id)
    assert rec["completion"] == "projective" and rec["completion_vp_inside"] is False
    assert summary.notes and "VP outside" in summary.notes[0]


def test_unlabelled_completion_gives_the_images_of_unlabelled_frames(tmp_path, camvid_half):
    """A study's test store (WarpSettings.unlabelled_completion): its labels (here a bonnet's ignore
    border) never shape the completion, so its images are the frames' images warped without labels
    (what vctrain predict builds); the record says so, and its key differs (a store built otherwise
    is rebuilt); the labels still ride along."""
    images, labels = write_synthetic_dataset(tmp_path / "ds", camvid_half, n=2, bonnet_rows=25)
    fmt = LABEL_FORMATS["camvid"]

    def build(out: str, labelled: bool, unlabelled: bool):
        jobs = list_dataset(images, labels if labelled else None, fmt if labelled else None)
        return warp_dataset(jobs, tmp_path / out, WarpSettings(
            PRESETS["camvid"], PRESETS["virtual"], 0.125, fmt if labelled else None, completion="projective",
            unlabelled_completion=unlabelled, progress=False))[0]

    plain, shaped, test = build("plain", False, False), build("shaped", True, False), build("test", True, True)
    for i in ("seq_0000", "seq_0001"):
        img = {s: cv2.imread(str(s.path(s.get(i)["image"]))) for s in (plain, shaped, test)}
        assert np.array_equal(img[test], img[plain]) and not np.array_equal(img[shaped], img[plain])
        assert test.get(i)["completion_unlabelled"] is True and "completion_unlabelled" not in shaped.get(i)
        assert test.get(i)["key"] != shaped.get(i)["key"] and test.get(i)["label"]


def test_thin_band_kitti():
    """KITTI frames (375 px high) cover a thin band of the virtual view; a 48-row crop around the
    horizon is thinner still. Both complete everything, from both sides of the band."""
    kitti = PRESETS["kitti"]
    agree = _agreement(kitti)
    assert agree["projective"] > 0.98
    band = kitti.resized(1, 1, size=(1242, 48))
    band = dataclasses.replace(band, cy=kitti.cy - 150)  # rows 150..197 of the frame
    img, lab, H, vp = _setup(band)
    maps = completion_maps(H, band.size, V8.size, "projective", vp)
    assert maps.vp_inside and maps.valid.mean() < 0.15
    assert (maps.map_x != OUTSIDE).all()
    assert set(np.unique(maps.map_y[maps.valid == 0].round())) >= {0.0, 47.0}  # top and bottom rows used


@pytest.mark.parametrize("kind", ["grey8", "grey16", "bgr16"])
def test_greyscale_and_16_bit(camvid_half, kind):
    img, lab, H, vp = _setup(camvid_half)
    maps = completion_maps(H, camvid_half.size, V8.size, "projective", vp)
    ref = warp_image(img, maps).astype(np.int32)
    src = {"grey8": cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), "grey16": cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.uint16) * 257,
           "bgr16": img.astype(np.uint16) * 257}[kind]
    out = warp_image(src, maps)
    assert out.dtype == src.dtype and out.shape == (350, 688) + src.shape[2:]
    assert out[maps.valid == 0].min() > 0  # filled (the render has no black)
    if kind == "bgr16":
        assert np.abs((out.astype(np.int32) + 128) // 257 - ref).max() <= 1
    if kind == "grey8":
        grey_ref = cv2.cvtColor(ref.astype(np.uint8), cv2.COLOR_BGR2GRAY).astype(np.int32)
        assert np.abs(out.astype(np.int32) - grey_ref).max() <= 2


def test_completing_a_completed_item_changes_nothing(camvid_half):
    img, lab, H, vp = _setup(camvid_half)
    maps = completion_maps(H, camvid_half.size, V8.size, "projective", vp)
    once = warp_image(img, maps)
    # a store image with no uncovered pixel left: completion maps of an identity warp leave it alone
    I = np.eye(3)
    again = completion_maps(I, V8.size, V8.size, "projective", vp)
    assert again.valid.all() and np.array_equal(warp_image(once, again, exact=True), once)


# -- commands --------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def dataset(tmp_path_factory, camvid_half):
    root = tmp_path_factory.mktemp("cds")
    images, labels = write_synthetic_dataset(root, camvid_half, n=2, bonnet_rows=25)
    return images, labels


def _warp(images, labels, out, *extra, run=run_cli):
    """``vcprep warp`` of the frames into the paper's store; ``run=run_here`` for a refusal before any item."""
    return run("warp", "--camera", "camvid", "--images", images, "--labels", labels, "--label-format", "camvid",
               "--out", out, "--quiet", *PAPER_STORE, *extra)


def _files(store: Path) -> dict[str, bytes]:
    return {str(p.relative_to(store)): p.read_bytes() for p in sorted(store.rglob("*.png"))}



def test_complete_command_equals_warp_complete_and_is_idempotent(dataset, tmp_path):
    images, labels = dataset
    a, b = tmp_path / "a", tmp_path / "b"
    assert _warp(images, labels, a).returncode == 0  # default: projective
    assert _warp(images, labels, b, "--complete", "zero").returncode == 0
    assert _files(a) != _files(b)
    proc = run_cli("complete", b, "--method", "projective")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(b) and "2 completed" in proc.stderr
    assert _files(a) == _files(b)
    assert (a / "manifest.jsonl").read_bytes() == (b / "manifest.jsonl").read_bytes()
    rec = json.loads((a / "manifest.jsonl").read_text().splitlines()[0])
    assert rec["completion"] == "projective" and rec["completion_vp_inside"] is True
    before = _files(b)
    proc = run_cli("complete", b)
    assert proc.returncode == 0 and "0 completed, 2 up to date" in proc.stderr
    assert _files(b) == before
    # warp with the same method is up to date too (same keys)
    proc = run_cli("warp", "--camera", "camvid", "--images", images, "--labels", labels, "--label-format", "camvid",
                   "--out", b, *PAPER_STORE)
    assert "0 built, 2 up to date" in proc.stderr
    lab = cv2.imread(str(a / "labels" / "seq_0000.png"), cv2.IMREAD_UNCHANGED)
    rec0 = json.loads((a / "manifest.jsonl").read_text().splitlines()[0])
    valid = cv2.imread(str(a / rec0["valid"]), cv2.IMREAD_UNCHANGED)
    assert (lab[valid == 0] != 255).all() and ((lab == 255) & (valid == 1)).any()  # bonnet kept, rest filled
    fig = tmp_path / "fig.png"
    proc = run_here("figure", "completion", a, "seq_0000", "-o", fig)
    assert proc.returncode == 0 and proc.stdout.strip() == str(fig)
    f = cv2.imread(str(fig))
    assert f.shape[1] == 1400 and f.shape[0] > 300


def test_complete_cli_errors(dataset, tmp_path):
    images, labels = dataset
    assert_one_error_line(run_here("complete", tmp_path / "nope"), "no such store directory")
    assert_one_error_line(_warp(images, labels, tmp_path / "x", "--complete", "mirror", run=run_here),
                          "unknown completion method")
    st = tmp_path / "st"
    assert _warp(images, labels, st, "--complete", "none").returncode == 0
    assert_one_error_line(run_here("complete", st, "--method", "bogus"), "unknown completion method", "projective")
    assert_one_error_line(run_here("figure", "completion", st, "no_such_id", "-o", tmp_path / "f.png"), "no item")
    # a source changed after warping: refuse, name the file, say how to fix
    moved = tmp_path / "imgs"
    moved.mkdir()
    for p in images.iterdir():
        (moved / p.name).write_bytes(p.read_bytes())
    st2 = tmp_path / "st2"
    proc = run_cli("warp", "--camera", "camvid", "--images", moved, "--out", st2, "--complete", "none", "--quiet",
                   *PAPER_STORE)
    assert proc.returncode == 0, proc.stderr
    victim = moved / "seq_0001.png"
    img = cv2.imread(str(victim))
    cv2.imwrite(str(victim), 255 - img)
    assert_one_error_line(run_cli("complete", st2), str(victim), "changed since the store was built")
    for cmd in (["complete", "--help"], ["figure", "completion", "--help"], ["warp", "--help"]):
        proc = run_cli(*cmd)
        assert proc.returncode == 0 and ("Example" in proc.stdout or "--complete" in proc.stdout)


@pytest.mark.parametrize("kind", ["bgr8", "grey8", "bgr16", "float32"])
@pytest.mark.parametrize("cut", [False, True])
def test_fused_pass_equals_the_one_remap_reference(camvid_half, kind, cut):
    """The fast path (covered pixels remapped, uncovered ones looked up in the angle table) gives
    exactly what one remap of every pixel through the completed float maps gives, on uncovered
    pixels; covered pixels are the bare warp's. Labels: identical to one nearest remap."""
    img, lab, H, vp = _setup(camvid_half, pan=3.0, tilt=2.0)
    lab = lab.copy()
    if cut:
        lab[-40:, 100:380] = 255
        lab[:, :12] = 255
    src = {"bgr8": img, "grey8": cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), "bgr16": img.astype(np.uint16) * 257,
           "float32": img.astype(np.float32) / 255}[kind]
    maps = completion_maps(H, camvid_half.size, V8.size, "projective", vp, border_ignore(lab))
    assert maps.fill is not None and (maps.angles.index[maps.valid == 1] == -1).all()
    fast, ref = warp_image(src, maps), warp_image(src, maps, exact=True)
    unc = maps.valid == 0
    assert fast.dtype == src.dtype and np.array_equal(fast[unc], ref[unc])
    bare = warp_image(src, maps_for(H, camvid_half.size, V8.size))
    assert np.array_equal(fast[~unc], bare[~unc])
    wl = warp_label(lab, maps, maps.label_border)
    one = cv2.remap(lab, maps.nearest, None, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=255)
    assert np.array_equal(wl, one)


def test_fill_gathers_and_chunks_agree(camvid_half, monkeypatch):
    """The fill's two gathers (torch.index_select when torch is loaded, a nearest cv2.remap
    otherwise; issue 81) give the same image, bit for bit, whole or in row chunks (a store larger
    than the chunk size is cut), and that image is the bare warp's on covered pixels and the
    one-remap reference's on uncovered ones."""
    import torch  # noqa: F401  (the torch gather runs only where torch is already imported)
    from vcprep.warp import completion as comp, completion_tables
    img, lab, H, vp = _setup(camvid_half, pan=3.0, tilt=2.0)
    maps = completion_maps(H, camvid_half.size, V8.size, "projective", vp, border_ignore(lab))
    outs = []
    for use_torch, chunk in ((True, 1 << 18), (False, 1 << 18), (True, 4096), (False, 4096)):
        monkeypatch.setattr(comp, "_FILL_TORCH", use_torch)
        monkeypatch.setattr(completion_tables, "CHUNK_PIXELS", chunk)
        outs.append(warp_image(img, maps))
    assert len(maps.angles.chunks(True)) > 1  # the small chunk size did cut the store
    for o in outs[1:]:
        assert np.array_equal(o, outs[0])
    unc = maps.valid == 0
    assert np.array_equal(outs[-1][unc], warp_image(img, maps, exact=True)[unc])
    assert np.array_equal(outs[-1][~unc], warp_image(img, maps_for(H, camvid_half.size, V8.size))[~unc])


# -- annotation rims (issue 16.2) --------------------------------------------------------------------

@pytest.mark.parametrize("method", ["projective", "replicate"])
def test_a_label_rim_is_not_completed(method):
    """KITTI's gt_image_2 marks its last rows 'not road' even under the road. Completion takes
    labels LABEL_RIM px inside the edge, so a rim up to that wide changes no completed pixel and
    the road continues below the frame, as the virtual camera rendered directly sees it."""
    kitti = PRESETS["kitti"]
    img, lab, H, vp = _setup(kitti)
    _, ref_lab = render_road(V8, SCENE, supersample=1)
    maps = completion_maps(H, kitti.size, V8.size, method, vp)
    unc = maps.valid == 0
    clean = warp_label(lab, maps, maps.label_border)
    for rows in (3, 5, LABEL_RIM):
        rim = lab.copy()
        rim[-rows:] = 0  # not road across the whole bottom band
        rim[:, :2] = 0   # and a rim on the left edge too
        np.testing.assert_array_equal(warp_label(rim, maps, maps.label_border)[unc], clean[unc])
    if method == "replicate":  # (replication is no geometric completion: only the rim independence holds)
        return
    below = unc & (np.arange(V8.size[1])[:, None] > vp[1]) & (ref_lab == 1)  # road under the frame
    assert below.sum() > 1000
    assert (clean[below] == 1).mean() > 0.99
    assert (clean[unc] == ref_lab[unc]).mean() > 0.98


def test_label_exit_points_are_inset():
    c = np.array([10.0, 5.0])
    dx, dy = np.array([1.0, 0.0, -1.0, 1.0]), np.array([0.0, 1.0, 0.0, 1.0])
    x, y = label_exit_points(c, dx, dy, (21, 11), rim=2)
    np.testing.assert_array_equal(x, [18, 10, 2, 13])  # the diagonal meets the inset bottom (y 8) at x 13
    np.testing.assert_array_equal(y, [5, 8, 5, 8])
    # a centre inside the rim is moved in first; an image thinner than two rims is sampled at its middle
    x, y = label_exit_points(np.array([0.0, 0.0]), np.array([1.0]), np.array([0.0]), (21, 3), rim=2)
    assert (x[0], y[0]) == (18, 1)


def test_real_kitti_frame_road_continues_below_it(tmp_path):
    """The shipped KITTI frame (its gt_image_2 has 4 rows of 'not road' and a 5th half of it under
    the road): below the frame, on the road VP's column, the completed label is road."""
    kitti = EXAMPLES / "kitti"
    out = tmp_path / "store"
    proc = run_cli("warp", "--camera", kitti / "calib" / "um_000000.txt", "--images", kitti / "image_2", "--labels",
                   kitti / "gt_image_2", "--label-format", "kitti", "--out", out, "--jobs", "1", "-q", *PAPER_STORE)
    assert proc.returncode == 0, proc.stderr
    rec = json.loads((out / "manifest.jsonl").read_text())
    assert rec["key"] and "completion" in rec
    lab = cv2.imread(str(out / rec["label"]), cv2.IMREAD_UNCHANGED)
    valid = cv2.imread(str(out / rec["valid"]), cv2.IMREAD_UNCHANGED)
    u = int(round(rec["completion_centre"][0]))
    last = int(np.flatnonzero(valid[:, u])[-1])
    column = lab[last + 1:, u]
    assert len(column) > 50 and (column == 1).all()
    # the frame's own bottom rows stay as annotated (the warp shows them; only completion skips them)
    assert (lab[last - 1:last + 1, u] == 0).any()
