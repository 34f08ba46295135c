"""``vcprep bev``: frames, labels and road masks onto a metric grid of the road plane, and the
road in metres (:func:`vcprep.bev.bev_folder`)."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer
from tqdm import tqdm

from ..bev.folder import BevSettings, bev_folder, find_masks
from ..bev.frames import within_rule
from ..bev.grid import parse_range
from ..bev.view import BevSource
from ..cliutil import check_data_folders, corridor_option, count, emit_json, err, range_option, res_option
from ..dataset import list_dataset
from ..labels import get_label_format
from .common import FRAMES_HELP, LABEL_FORMAT_HELP, WITHIN_HELP, app, camera_for, check_label_format

@app.command("bev")
def bev_cmd(
    camera: str = typer.Option(..., "--camera", "-c", help=FRAMES_HELP + ", or 'estimate': estimated from these "
                               "frames; a KITTI calib file with Tr_cam_to_road: the road benchmark devkit's transform"),
    images: Path = typer.Option(..., "--images", "-i", help="folder of frames (subfolders included)"),
    out: Path = typer.Option(..., "--out", "-o", help="folder for the BEV PNGs (created)"),
    labels: Optional[Path] = typer.Option(None, "--labels", "-l", help="folder of labels, a tree mirroring --images"),
    label_format: Optional[str] = typer.Option(None, "--label-format", "-f", help=LABEL_FORMAT_HELP),
    masks: Optional[Path] = typer.Option(None, "--masks", "-m", help="folder of road masks or probability maps "
                                         "(<stem>_mask.png / <stem>_prob.png, as 'vctrain predict' writes them)"),
    grid_range: Optional[str] = range_option(),
    res: float = res_option(),
    within: Optional[str] = typer.Option(None, "--within", help=WITHIN_HELP + "; default 'estimate' for one camera, "
                                         "'none' for calibration files (each frame's exact pose)"),
    corridor: float = corridor_option(),
    roll: float = typer.Option(0.0, "--roll", help="the camera's roll about its optical axis in degrees (image "
                               "turned clockwise > 0), if known: frames and camera files do not tell it"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar or summary on stderr"),
):
    """Frames (and their labels or road masks) onto a metric grid of the road plane: a bird's-eye
    view, far row first, and the road in metres.

    Each frame is projected through its own pose, from its road vanishing point by default
    (--within estimate, the warp's rule), or the camera's nominal pose (--within none); a KITTI
    road calibration file (or folder of them) with Tr_cam_to_road gives the road benchmark
    devkit's exact transform. Writes OUT/<id>_image.png (bilinear), <id>_label.png and
    <id>_mask.png (0 not road, 1 road, 255 unseen or ignore: cells the camera does not see are
    never guessed) and <id>_prob.png (0-255, unseen 0). With --labels or --masks it prints one
    JSON line per frame: free_m (how far the --corridor ahead is road, from the camera; a hole or
    object under 0.5 m both ways does not end it; free_to_edge, free_stop; start_m, start_why: why
    the corridor starts past the grid's first row, e.g. the label's border rows), width_m (the
    width of the road the vehicle drives on 10, 20 and 30 m ahead, holes under 0.5 m filled, null
    where not all in view; edges_m, and others_m: the separate road beside it), area_m2 and pose;
    without, it prints OUT.

    \b
    Example:
      vcprep bev --camera examples/kitti/calib --images examples/kitti/image_2 \\
          --labels examples/kitti/gt_image_2 --label-format kitti --out bev/kitti
      vcprep bev --camera camvid --images data/camvid/val --masks preds/camvid_val \\
          --range=-8,8,4,40 --res 0.1 --out bev/camvid
    """
    check_label_format(labels, label_format)
    check_data_folders(images, labels)
    grid = parse_range(grid_range, res)
    fmt = get_label_format(label_format) if label_format else None
    jobs = list_dataset(images, labels, fmt)
    spec = camera
    if camera == "estimate":
        source = BevSource(camera_for(camera, frames=[j.image for j in jobs], quiet=quiet))
    else:
        source = BevSource.from_spec(spec, jobs[0].image)
    rule = within_rule(within, source, spec)
    found = find_masks(masks, jobs) if masks is not None else None
    settings = BevSettings(grid=grid, within=rule, corridor=corridor, label_format=fmt, roll=roll)
    bar = tqdm(total=len(jobs), desc="vp", unit="img", disable=True if quiet or rule != "estimate" else None,
               leave=False)
    n = 0
    out.mkdir(parents=True, exist_ok=True)
    for record in bev_folder(jobs, source, out, settings, found, lambda i: bar.update()):
        emit_json(record)
        n += 1
    bar.close()
    if labels is None and masks is None:
        print(out)
    if not quiet:
        rows, cols = grid.shape
        err(f"{out}: {count(len(jobs), 'frame')} onto {cols}x{rows} cells of {res:g} m "
            f"(x {grid.x_min:g}..{grid.x_max:g}"
            f" m, z {grid.z_min:g}..{grid.z_max:g} m), poses: {rule}")
