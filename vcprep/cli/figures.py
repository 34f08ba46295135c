"""Figures (PNG): ``figure prior|warp|completion|footprints|fov|camera|vp``."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ..camera.sources import load_camera
from ..cliutil import count
from ..errors import InputError
from ..figures import (camera_figure, completion_figure, evenly_spread, footprints_figure, fov_figure, prior_figure,
                       vp_figure_of_file, warp_figure)
from ..prior import check_thresholds, mean_image, open_stores, prior_counts, prior_from_counts
from ..store.layout import Store
from ..vp.reliability import read_vp_csv
from .common import CAMERA_HELP, ESTIMATE_HELP, camera_for, figure_app, image_files, save_figure


@figure_app.command("prior")
def figure_prior(stores: List[Path] = typer.Argument(..., help="labelled stores of one virtual camera and scale"),
                 out: Path = typer.Option(..., "-o", "--out", help="PNG to write"),
                 lo: float = typer.Option(0.25, "--lo", help="lower contour (surrogate 'not road' below it)"),
                 hi: float = typer.Option(0.75, "--hi", help="upper contour (surrogate 'road' above it)"),
                 width: int = typer.Option(1100, help="figure width in pixels")):
    """The geometric road prior of the stores as a heat map over their mean image, with the
    --lo/--hi contours that bound the surrogate labels of 'vctrain adapt'; pixels no item labels
    show the mean image only.

    \b
    Example:
      vcprep figure prior stores/camvid stores/kitti -o prior.png
    """
    check_thresholds(lo, hi)
    opened = open_stores(stores)
    road, known, n = prior_counts(opened)
    prior = prior_from_counts(road, known)
    caption = f"{count(n, 'labelled item')}, {count(int((known == 0).sum()), 'pixel')} unlabelled"
    save_figure(out, prior_figure(prior, mean_image(opened), known == 0, (lo, hi), caption, width=width))


@figure_app.command("warp")
def figure_warp(store: Path = typer.Argument(..., help="store directory"),
                out: Path = typer.Option(..., "-o", "--out", help="PNG to write"),
                ids: Optional[List[str]] = typer.Option(None, "--id", help="item id (repeatable; default: up to 6)"),
                width: int = typer.Option(1400, help="figure width in pixels")):
    """Side-by-side figure per item: original (with label) | virtual camera (with label and
    the covered region outlined).

    \b
    Example:
      vcprep figure warp stores/camvid -o warp.png --id 0001TP_006690
    """
    save_figure(out, warp_figure(Store.open(store), ids or None, width=width))


@figure_app.command("completion")
def figure_completion(store: Path = typer.Argument(..., help="store directory"),
                      item: str = typer.Argument(..., help="item id"),
                      out: Path = typer.Option(..., "-o", "--out", help="PNG to write"),
                      rays: int = typer.Option(24, "--rays", help="number of completion rays to draw"),
                      width: int = typer.Option(1400, help="figure width in pixels")):
    """Projective completion of one item, like the paper's Fig. 5: completed image with the VP
    (red), the source boundary (red dashed) and a fan of completion rays (green) | completed
    label overlay (road green, ignore dark).

    \b
    Example:
      vcprep figure completion stores/camvid 0001TP_006690 -o completion.png
    """
    save_figure(out, completion_figure(Store.open(store), item, rays=rays, width=width))


@figure_app.command("footprints")
def figure_footprints(cameras: List[str] = typer.Argument(..., help=CAMERA_HELP),
                      out: Path = typer.Option(..., "-o", "--out", help="PNG to write"),
                      fraction: float = typer.Option(0.25, help="lower fraction of each image to map (paper: 0.25)")):
    """Ground-plane footprint of the lower part of each camera's view, top view (paper Fig. 3).

    \b
    Example:
      vcprep figure footprints camvid cityscapes kitti qian toronto2020 -o footprints.png
    """
    if not 0 < fraction <= 0.5:
        raise InputError(f"--fraction {fraction} is out of range", None, "use a value in (0, 0.5]")
    save_figure(out, footprints_figure([load_camera(c) for c in cameras], fraction=fraction))


@figure_app.command("fov")
def figure_fov(cameras: List[str] = typer.Argument(..., help=CAMERA_HELP),
               out: Path = typer.Option(..., "-o", "--out", help="PNG to write"),
               virtual: str = typer.Option("virtual", "--virtual", help="virtual camera: preset or YAML file")):
    """Each camera's field of view drawn in the virtual image plane (paper Fig. 4).

    \b
    Example:
      vcprep figure fov camvid cityscapes kitti qian toronto2020 --virtual virtual -o fov.png
    """
    save_figure(out, fov_figure([load_camera(c) for c in cameras], load_camera(virtual)))


@figure_app.command("camera")
def figure_camera(camera: str = typer.Argument(..., help=CAMERA_HELP + ESTIMATE_HELP),
                  images: List[Path] = typer.Argument(..., help="frames of this camera: files or folders"),
                  out: Path = typer.Option(..., "-o", "--out", help="PNG to write"),
                  vps: Optional[Path] = typer.Option(None, "--vps", help="CSV of the frames' road VPs (vcprep vp, "
                                                     "vcprep camera estimate --vps): drawn as red +"),
                  samples: int = typer.Option(4, "--samples", min=1, max=32, help="frames drawn, evenly spread"),
                  width: int = typer.Option(1400, "--width", min=200, help="figure width in pixels")):
    """Draw a camera on sample frames to see in one look whether it is right: the horizon and
    the camera's average road VP (cyan), each frame's own road VP (red +, with --vps), the own
    vehicle's rows (red band), the principal point (white dot).

    \b
    Example:
      vcprep camera estimate data/dashcam -o dashcam.yaml --vps dashcam_vps.csv
      vcprep figure camera dashcam.yaml data/dashcam --vps dashcam_vps.csv -o dashcam.png
    """
    files = image_files(images)
    pick = evenly_spread(files, samples)
    cam = camera_for(camera, pick[0], per_frame=False, frames=files)
    save_figure(out, camera_figure(pick, cam, read_vp_csv(vps) if vps else None, width=width))


@figure_app.command("vp")
def figure_vp(image: Path = typer.Argument(..., help="image file"),
              camera: str = typer.Option(..., "--camera", "-c", help=CAMERA_HELP),
              out: Path = typer.Option(..., "-o", "--out", help="PNG to write")):
    """Draw why a road VP was chosen or rejected: all line segments (grey), the supporting
    ones (green, thin lines to the VP), the window of VPs the reliability rule allows (cyan),
    the detected VP (red cross), the final VP (yellow circle) and the status with its reason.
    A single image has no dataset to fall back to: a rejected VP falls back to the camera's
    average-pose VP.

    \b
    Example:
      vcprep figure vp examples/camvid/images/0016E5_05280.png --camera camvid -o vp.png
    """
    save_figure(out, vp_figure_of_file(image, camera_for(camera, image, per_frame=False)))
