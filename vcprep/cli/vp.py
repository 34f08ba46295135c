"""The road vanishing point command: ``vp``."""
from __future__ import annotations

import sys
from pathlib import Path
from typing import List, Optional

import typer
from tqdm import tqdm

from ..cliutil import count, emit_json, ensure_parent, err
from ..vp.reliability import estimate_files, format_vp_csv, write_vp_csv
from .common import CAMERA_HELP, ESTIMATE_HELP, SMOOTH_HELP, app, camera_for, image_files, vp_counts


@app.command("vp")
def vp_cmd(images: List[Path] = typer.Argument(..., help="image files or folders of images"),
           camera: str = typer.Option(..., "--camera", "-c", help=CAMERA_HELP + ESTIMATE_HELP),
           out: Optional[Path] = typer.Option(None, "-o", "--out", help="CSV 'id,u,v,status,...' to write"),
           as_json: bool = typer.Option(False, "--json", help="one JSON object per image on stdout"),
           smooth: int = typer.Option(0, "--smooth", min=0, help=SMOOTH_HELP),
           quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar or summary on stderr")):
    """Detect the road vanishing point (VP) of each image, with the reliability rule:
    a VP whose implied pan is more than 20 deg (tilt 15 deg) from the camera's average pose,
    or with too few supporting line segments, is replaced by the mean of the accepted VPs of
    its sequence (the id up to the first '_', e.g. 0016E5; when it has at least 3), else of
    this run (status 'fallback'; with none accepted, the camera's average-pose VP).

    Prints CSV (id,u,v,status,confidence,n_support,pan_deg,tilt_deg; u, v in source pixels)
    to stdout, or writes it to --out and prints the path; --json prints one object per image
    instead (image = the path as given). The CSV is what 'vcprep warp --within FILE' reads.

    \b
    Example:
      vcprep vp --camera camvid data/camvid/val -o vps.csv
      vcprep vp --camera camvid examples/camvid/images/*.png --json | jq -c '[.status, .vp]'
    """
    files = image_files(images, ("duplicate image id", "VP files are keyed by file stem: give each image a unique name"))
    ids = [f.stem for f in files]
    cam = camera_for(camera, files[0], per_frame=False, frames=files, quiet=quiet)
    bar = tqdm(total=len(files), desc="vp", unit="img", disable=True if quiet else None, leave=False)
    try:
        results = estimate_files(files, cam, smooth=smooth, ids=ids, on_image=lambda i: bar.update())
    finally:
        bar.close()
    if out is not None:
        write_vp_csv(ensure_parent(out), ids, results)
    if as_json:
        for f, i, r in zip(files, ids, results):
            emit_json({"image": str(f), "id": i, **r.to_dict()})
    elif out is not None:
        print(out)
    else:
        sys.stdout.write(format_vp_csv(ids, results))
    if not quiet:
        err(f"{count(len(results), 'image')}: {vp_counts(results)}")
