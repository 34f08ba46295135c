"""Simulating another camera: ``simulate``."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ..cliutil import check_data_folders, err, parse_size
from ..dataset import list_dataset
from ..labels import get_label_format
from ..simulate.plan import SimulateParams
from ..simulate.writer import simulate_dataset
from .common import CAMERA_HELP, LABEL_FORMAT_HELP, app, camera_for, check_label_format


@app.command("simulate")
def simulate_cmd(
    camera: str = typer.Option(..., "--camera", "-c", help=CAMERA_HELP),
    images: Path = typer.Option(..., "--images", "-i", help="folder of source images"),
    out: Path = typer.Option(..., "--out", "-o", help="output dataset folder (new, empty, or an earlier simulate output)"),
    labels: Optional[Path] = typer.Option(None, "--labels", "-l", help="folder of label images (warped by nearest "
                                          "neighbour, raw values and file names kept)"),
    label_format: Optional[str] = typer.Option(None, "--label-format", "-f",
                                               help=LABEL_FORMAT_HELP),
    size: Optional[str] = typer.Option(None, "--size", help="output WIDTHxHEIGHT in pixels (default: the source size)"),
    hfov: Optional[float] = typer.Option(None, "--hfov", help="output horizontal field of view, degrees edge to edge "
                                         "(default: the widest that every image covers)"),
    zoom: Optional[float] = typer.Option(None, "--zoom", help="focal length factor fx' = zoom*fx (instead of --hfov)"),
    pan: float = typer.Option(0.0, "--pan", help="pan change, degrees (the road VP moves right for > 0)"),
    tilt: float = typer.Option(0.0, "--tilt", help="tilt change, degrees, positive = pitched further down"),
    roll: float = typer.Option(0.0, "--roll", help="roll, degrees, positive = the picture turns clockwise"),
    pan_jitter: float = typer.Option(0.0, "--pan-jitter", help="per-image pan drawn in [-D, +D] degrees"),
    tilt_jitter: float = typer.Option(0.0, "--tilt-jitter", help="per-image tilt drawn in [-D, +D] degrees"),
    roll_jitter: float = typer.Option(0.0, "--roll-jitter", help="per-image roll drawn in [-D, +D] degrees"),
    seed: int = typer.Option(0, "--seed", help="seed of the per-image draws (each depends on seed and image id only)"),
    horizon_shift: float = typer.Option(0.0, "--horizon-shift", help="move the principal point (and the horizon) "
                                        "down by PX output pixels (negative: up); an exact crop"),
    greyscale: bool = typer.Option(False, "--greyscale", help="write 3-channel grey images"),
    flip: bool = typer.Option(False, "--flip", help="mirror images and labels left-right (left-hand traffic)"),
    vps: Optional[Path] = typer.Option(None, "--vps", help="CSV 'id,u,v' of the source images' road VPs (source "
                                       "pixels, e.g. from 'vcprep vp'); default: the camera's nominal pose"),
    name: Optional[str] = typer.Option(None, "--name", help="name of the simulated camera (default: OUT's name)"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar or summary on stderr"),
):
    """Create a new dataset as if shot by another camera at the same place: re-mounted (pan,
    tilt, roll, fixed or drawn per image), zoomed and cropped (--hfov/--zoom, --size,
    --horizon-shift), optionally grey or mirrored. Prints OUT.

    Exact for any scene: rotating a camera about its optical centre is the homography
    K' R K^-1 and zoom/crop only change K. A change of camera HEIGHT is not offered: it moves
    the optical centre and cannot be simulated exactly from one image. Every output pixel
    comes from inside its source image: without --hfov/--zoom the widest such field of view
    over all images is chosen (and reported); a given one that leaves a source is an error
    naming the widest that works.

    Writes OUT/images/<stem>.png (bilinear), OUT/labels/<label name>.png (nearest, raw values:
    the same --label-format reads them), OUT/camera.yaml (the new camera at its nominal
    pose; no roll in the camera model), OUT/vps.csv (id,u,v: each source VP mapped
    exactly, so as good as the source VP), OUT/poses.csv (id,pan_deg,tilt_deg,roll_deg: pan
    and tilt of that VP in the new camera, and the roll) and OUT/simulate.json (everything
    needed to reproduce it). Re-running skips images whose outputs are up to date.

    \b
    Example:
      # a telephoto camera tilted 3 deg further down, 320x240
      vcprep simulate --camera camvid --images data/camvid/val --labels data/camvid/valannot \\
          --label-format camvid --out sim/tele --hfov 35 --tilt 3 --size 320x240
      # a KITTI-like wide band (widest field of view the frames cover)
      vcprep simulate --camera camvid --images data/camvid/val --out sim/band --size 480x146
      # a dashcam re-mounted differently in every frame
      vcprep simulate --camera camvid --images data/camvid/val --out sim/dashcam \\
          --pan-jitter 10 --tilt-jitter 5 --seed 1
    """
    check_label_format(labels, label_format)
    fmt = get_label_format(label_format) if label_format else None
    out_size = parse_size(size) if size is not None else None
    check_data_folders(images, labels)
    jobs = list_dataset(images, labels, fmt)
    cam = camera_for(camera, jobs[0].image, per_frame=False)
    params = SimulateParams(size=out_size, hfov=hfov, zoom=zoom, pan=pan, tilt=tilt, roll=roll, pan_jitter=pan_jitter,
                            tilt_jitter=tilt_jitter, roll_jitter=roll_jitter, seed=seed, horizon_shift=horizon_shift,
                            greyscale=greyscale, flip=flip, name=name)
    plan, summary = simulate_dataset(jobs, cam, out, params, fmt, vps_file=vps, progress=not quiet)
    if not quiet:
        err(f"{out}: {summary.line()}")
        c = plan.camera
        err(f"camera {c.name}: fx {c.fx:.2f}, fy {c.fy:.2f}, cx {c.cx:.2f}, cy {c.cy:.2f}, "
            f"pan {c.pan:.2f}, tilt {c.tilt:.2f} deg")
        for n in summary.notes:
            err(f"warning: {n}")
    print(out)
