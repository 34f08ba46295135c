"""The road in metres (vcprep.bev.metres) against BEV masks built on the grid with known geometry.

Every mask here is drawn cell by cell from metres (a road x in [-3.5, 3.5), a hole of 0.45 m, a
barrier at 25 m, a pavement beyond a 1 m gap), so each expected value is exact: the free distance is
the near edge of the first blob of at least 0.5 m, the width that of the road runs under the corridor,
holes under 0.5 m both ways filled. The same rules through `vcprep bev --labels` on a rendered
road: tests/test_bev.py.
"""
from __future__ import annotations

import numpy as np
import pytest

from vcprep.bev import BevGrid, road_in_metres
from vcprep.bev.border import bottom_rows_why, label_border_rows
from vcprep.bev.metres import fill_small_holes

GRID = BevGrid()  # x -10..10, z 6..46 m, 0.05 m cells
X = GRID.x_centres()[None, :]
Z = GRID.z_centres()[:, None]


def _road(x0: float = -3.5, x1: float = 3.5) -> np.ndarray:
    """A straight road x in [x0, x1) over the whole grid, everything seen (0 not road, 1 road)."""
    return np.broadcast_to(((X >= x0) & (X < x1)).astype(np.uint8), GRID.shape).copy()


def _box(bev: np.ndarray, x0: float, x1: float, z0: float, z1: float, value: int) -> np.ndarray:
    bev[(X >= x0) & (X < x1) & (Z >= z0) & (Z < z1)] = value
    return bev


def test_a_straight_free_road_is_free_to_the_edge_and_7_m_wide():
    r = road_in_metres(_road(), GRID)
    assert r["free_m"] == 46.0 and r["free_to_edge"] is True and r["free_stop"] == "edge"
    assert r["start_m"] == 6.0 and r["start_why"] is None
    assert r["width_m"] == {"10": 7.0, "20": 7.0, "30": 7.0}
    assert r["edges_m"]["10"] == [-3.5, 3.5] and r["others_m"]["10"] == []


def test_a_hole_under_half_a_metre_does_not_end_the_corridor_one_of_half_a_metre_does():
    arrow = _box(_road(), -0.2, 0.25, 20.0, 20.45, 0)  # 9 x 9 cells: 0.45 m both ways
    r = road_in_metres(arrow, GRID)
    assert r["free_to_edge"] is True and r["free_m"] == 46.0
    assert r["width_m"]["20"] == 7.0  # the hole is filled: the road is as wide there
    noise = _road()
    for z in np.arange(8.0, 44.0, 2.0):  # a speck every 2 m, inside the corridor
        _box(noise, 0.3, 0.6, z, z + 0.3, 0)
    assert road_in_metres(noise, GRID)["free_to_edge"] is True
    hole = _box(_road(), -0.25, 0.25, 20.0, 20.5, 0)  # 10 x 10 cells: 0.5 m both ways
    r = road_in_metres(hole, GRID)
    assert r["free_m"] == 20.0 and r["free_to_edge"] is False and r["free_stop"] == "not road"
    long = _box(_road(), 0.0, 0.3, 15.0, 18.0, 0)  # narrow but 3 m along the road: an object, it stops
    assert road_in_metres(long, GRID)["free_m"] == 15.0


def test_a_barrier_across_the_road_ends_it_at_its_near_edge():
    wall = _box(_road(), -3.5, 3.5, 25.0, 25.2, 0)  # 0.2 m deep, across the road
    r = road_in_metres(wall, GRID)
    assert r["free_m"] == 25.0 and r["free_stop"] == "not road" and r["free_to_edge"] is False
    at_edge = _box(_road(), -3.5, 3.5, 45.8, 46.0, 0)  # at the grid's far edge: not free to it
    r = road_in_metres(at_edge, GRID)
    assert r["free_m"] == 45.8 and r["free_to_edge"] is False
    small_at_edge = _box(_road(), 0.0, 0.2, 45.9, 46.0, 0)  # even a speck at the far row: beyond is unknown
    assert road_in_metres(small_at_edge, GRID)["free_to_edge"] is False


def test_the_view_ending_stops_the_corridor_as_unseen():
    bev = _road()
    bev[Z[:, 0] >= 29.9] = 255  # the camera sees no farther than 29.9 m (the 30 m row: z in (29.95, 30])
    r = road_in_metres(bev, GRID)
    assert r["free_m"] == 29.9 and r["free_stop"] == "unseen"
    assert r["width_m"]["30"] is None and r["width_m"]["20"] == 7.0


def test_width_is_the_vehicles_road_a_pavement_beyond_a_gap_is_reported_apart():
    bev = _box(_road(), 4.5, 6.5, 6.0, 46.0, 1)  # pavement 4.5..6.5 m right, 1 m of not road between
    bev = _box(bev, -6.0, -4.0, 6.0, 46.0, 1)  # the opposite carriageway's lane beyond a 0.5 m median
    for z in (9.8, 19.8, 29.8):  # specks left out (0.3 x 0.3 m) in the rows measured: holes, filled
        _box(bev, 1.5, 1.8, z, z + 0.3, 0)
    r = road_in_metres(bev, GRID)
    assert r["width_m"] == {"10": 7.0, "20": 7.0, "30": 7.0}
    assert r["others_m"]["10"] == [2.0, 2.0] and r["edges_m"]["20"] == [-3.5, 3.5]
    assert r["area_m2"] == pytest.approx((7.0 + 2.0 + 2.0) * 40.0 - 3 * 0.3 * 0.3)
    kerb = _box(_road(-3.5, 6.0), 3.5, 3.8, 6.0, 46.0, 0)  # a pavement beyond a 0.3 m kerb: narrow, but long
    r = road_in_metres(kerb, GRID)
    assert r["width_m"]["20"] == 7.0 and r["others_m"]["20"] == [2.2]
    line = _box(_road(), 1.7, 1.85, 6.0, 46.0, 0)  # a lane line the model left out separates too: the own lane
    assert road_in_metres(line, GRID)["width_m"]["10"] == 5.2


def test_a_car_on_the_road_is_not_counted_and_a_later_junction_does_not_merge_a_pavement():
    bev = _box(_road(), -1.0, 1.0, 18.0, 22.0, 0)  # a car 2 m wide in the corridor, 18..22 m
    _box(bev, 4.5, 6.5, 6.0, 46.0, 1)  # a pavement beyond a 1 m gap ...
    _box(bev, 3.5, 4.5, 35.0, 37.0, 1)  # ... joined to the road 35 m ahead (a driveway)
    r = road_in_metres(bev, GRID)
    assert r["width_m"]["20"] == 5.0 and r["edges_m"]["20"] == [-3.5, 3.5]  # the drivable width, the car left out
    assert r["others_m"]["20"] == [2.0] and r["width_m"]["10"] == 7.0 and r["free_m"] == 18.0


def test_width_follows_the_vehicles_region_where_the_road_leaves_the_corridor():
    bev = np.zeros(GRID.shape, np.uint8)
    _box(bev, -3.5, 3.5, 6.0, 22.0, 1)   # the vehicle's road ...
    _box(bev, -3.5, 9.0, 20.0, 22.0, 1)  # ... turning right ...
    _box(bev, 4.0, 9.0, 20.0, 46.0, 1)   # ... runs on at x 4..9 m, beside the corridor
    _box(bev, -9.0, -5.0, 25.0, 46.0, 1)  # another road, not joined to it
    r = road_in_metres(bev, GRID)
    assert r["width_m"]["10"] == 7.0 and r["width_m"]["30"] == 5.0 and r["edges_m"]["30"] == [4.0, 9.0]
    assert r["others_m"]["30"] == [4.0] and r["free_m"] == 22.0


def test_a_width_not_all_in_view_is_null():
    r = road_in_metres(_road(-12.0, 3.5), GRID)  # runs into the grid's left side
    assert r["width_m"] == {"10": None, "20": None, "30": None}
    bev = _road()
    bev[:, X[0] < -3.0] = 255  # an unseen strip touches the road's left edge
    assert road_in_metres(bev, GRID)["width_m"]["10"] is None


def test_a_first_row_that_is_not_road_says_why():
    hidden = np.zeros(GRID.shape, bool)
    hidden[Z[:, 0] < 6.3] = True  # what a label's border rows cover
    bev = _road()
    bev[hidden] = 0
    rows, why = bottom_rows_why(0, 4)
    r = road_in_metres(bev, GRID, hidden=hidden, hidden_why=why)
    assert r["free_to_edge"] is True and r["start_m"] == 6.3 and r["start_why"].startswith("label border")
    plain = road_in_metres(bev, GRID)  # without knowing: the first row is not road, and the corridor ends there
    assert plain["free_m"] == 6.0 and plain["start_why"] == "not road"
    unseen = _road()
    unseen[Z[:, 0] < 7.0] = 255
    r = road_in_metres(unseen, GRID)
    assert r["start_m"] == 7.0 and r["start_why"] == "unseen" and r["free_to_edge"] is True
    assert bottom_rows_why(40, 4)[1].startswith("own vehicle")


def test_label_border_rows_are_the_bottom_rows_without_road():
    label = np.zeros((375, 1242), np.uint8)
    label[200:371, 300:900] = 1
    assert label_border_rows(label) == 4  # KITTI road's gt_image_2
    label[371:] = 255
    assert label_border_rows(label) == 4  # ignore rows are no road either
    assert label_border_rows(np.ones((10, 10), np.uint8)) == 0
    tall = np.zeros((100, 10), np.uint8)
    tall[:50] = 1
    assert label_border_rows(tall) == 0  # half the frame is no border


def test_fill_small_holes_fills_blobs_under_the_size_both_ways_only():
    road = np.ones((40, 40), bool)
    road[5:8, 5:8] = False   # 3 x 3: filled
    road[20:24, 5:7] = False  # 4 long: stays at 4 cells
    road[:, 30] = False       # a line the whole way: stays
    got = fill_small_holes(road, 1.0, 4.0)
    assert got[5:8, 5:8].all() and not got[20:24, 5:7].any() and not got[:, 30].any()


def test_a_hole_of_one_pixel_row_far_ahead_is_judged_by_what_the_pixel_can_tell():
    """20 m ahead of a 480x270 camera 70 degrees wide, 1.5 m high, one pixel row covers 0.78 m of road:
    a hole of one pixel row (6 pixels, 0.35 m, across) may be anything up to that long, so with the
    frame's view it does not end the corridor; three rows (2.3 m) do. Without a view, cells are exact."""
    from vcprep.bev import bev_maps, camera_view, to_bev
    from vcprep.bev.metres import pixel_footprint
    from vcprep.camera import Camera

    w, h = 480, 270
    f = (w / 2) / np.tan(np.radians(35.0))
    cam = Camera("c", (w, h), f, f, (w - 1) / 2, (h - 1) / 2, 1.5, 0.0)
    view, grid = camera_view(cam), BevGrid(-4.0, 4.0, 6.0, 30.0, 0.05)
    maps = bev_maps(view, grid)
    v20 = int(round(cam.cy + f * 1.5 / 20.0))  # the pixel row 20 m ahead
    foot_z = pixel_footprint(view, grid)[0][grid.row_at(20.0)]
    assert foot_z == pytest.approx(20.0 ** 2 / (f * 1.5), rel=0.05)  # z^2 / (f h)
    for rows, ends in ((1, False), (3, True)):
        label = np.ones((h, w), np.uint8)
        label[v20 - rows + 1:v20 + 1, 237:243] = 0
        bev = to_bev(label, maps, "label")
        assert (road_in_metres(bev, grid, view)["free_to_edge"] is False) == ends, rows
        assert road_in_metres(bev, grid)["free_to_edge"] is False  # cell-exact: 0.78 m along the road ends it


def _synthetic_frame(tmp_path, holes=True):
    """A 1280x720 camera 1.6 m high, level (a camera file), one frame and its label drawn from the
    road plane: a road x in [-3.5, 3.5) with a 0.3 x 0.3 m hole (a lane arrow the labeller left out)
    10 m ahead in the corridor, 1 m of not road, a pavement strip x in [4.5, 6.0) labelled road (the
    frame sees 6.4 m to the right 10 m ahead)."""
    import cv2

    from vcprep.camera import Camera, camera_to_yaml
    from vcprep.synthetic import RoadScene, ground_points, render_road

    cam = Camera("synthetic", (1280, 720), 1000.0, 1000.0, 639.5, 359.5, 1.6, 0.0)
    (tmp_path / "cam.yaml").write_text(camera_to_yaml(cam))
    for d in ("images", "labels"):
        (tmp_path / d).mkdir()
    x, z, hit = ground_points(cam)
    road = hit & (((x >= -3.5) & (x < 3.5)) | ((x >= 4.5) & (x < 6.0)))
    if holes:
        road &= ~((x >= -0.15) & (x < 0.15) & (z >= 10.0) & (z < 10.3))
    cv2.imwrite(str(tmp_path / "images" / "f.png"), render_road(cam, RoadScene(width=7.0), supersample=1)[0])
    cv2.imwrite(str(tmp_path / "labels" / "f.png"), road.astype(np.uint8))
    return tmp_path


def test_vcprep_bev_labels_on_a_synthetic_road_arrow_pavement_and_free_edge(tmp_path):
    import json

    from conftest import run_cli

    d = _synthetic_frame(tmp_path)
    r = run_cli("bev", "--camera", str(d / "cam.yaml"), "--images", str(d / "images"), "--labels", str(d / "labels"),
                "--label-format", "values:road=1;ignore=255", "--within", "none", "--out", str(d / "out"), "--quiet")
    assert r.returncode == 0, r.stderr
    rec = json.loads(r.stdout)
    # the hole (0.3 m) does not end the corridor: the road is free to the grid's far edge, and says so
    assert rec["free_m"] == 46.0 and rec["free_to_edge"] is True and rec["free_stop"] == "edge"
    assert rec["start_why"] is None and rec["start_m"] == 6.0
    # the width is the vehicle's road, 7 m; the pavement beyond the 1 m gap is reported apart (1.5 m)
    for dist in ("10", "20", "30"):  # within a BEV cell and a pixel (0.03 m at 30 m) of each edge
        assert abs(rec["width_m"][dist] - 7.0) <= 0.1, rec["width_m"]
        assert len(rec["others_m"][dist]) == 1 and abs(rec["others_m"][dist][0] - 1.5) <= 0.1, rec["others_m"]
