"""``vctrain eval``: road IoU and the KITTI road metrics of predictions against labels
(:func:`vctrain.evaluate.evaluate_folder`)."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from vcprep.cliutil import count, emit_json, err, range_option, res_option

from .common import LABEL_FORMAT_HELP, app


MAXF_NOTE = ("# iou, precision, recall, f1: the masks (P >= 0.5); maxf: KITTI's max F1 over all thresholds of P "
             "(at kitti_threshold), above f1 when 0.5 is not the best threshold (F1 = 2 IoU / (1 + IoU))")


@app.command("eval")
def eval_cmd(
    pred_dir: Path = typer.Argument(..., help="folder of <stem>_mask.png / <stem>_prob.png from 'vctrain predict'"),
    labels: Path = typer.Option(..., "--labels", "-l", help="folder of ground-truth labels"),
    label_format: str = typer.Option(..., "--label-format", "-f", help=LABEL_FORMAT_HELP),
    as_json: bool = typer.Option(False, "--json", help="print one JSON object (values in [0, 1])"),
    bev: bool = typer.Option(False, "--bev", help="also score in the bird's-eye view of the road (under 'bev'): the "
                             "KITTI road benchmark's BEV evaluation; needs --camera"),
    camera: Optional[str] = typer.Option(None, "--camera", "-c", help="with --bev: the frames' camera (preset, file, "
                                         "or folder of per-frame calibration files: KITTI calib/ gives the devkit's "
                                         "transform2BEV), at the pose of --within (calibrated frames: their calibration)"),
    within: str = typer.Option("auto", "--within", help="with --bev: each frame's pose: auto (the pose 'vctrain "
                               "predict --bev' gave it, kept in predict.json: its road VP by default; the camera's "
                               "nominal pose where none is kept) or none (the camera's nominal pose); said on stderr"),
    run: Optional[int] = typer.Option(None, "--run", min=1, help="score the frames of this predict run alone (1, 2, "
                                      "...: a folder that holds several runs' frames names them)"),
    grid_range: Optional[str] = range_option("with --bev: "),
    res: float = res_option("with --bev: "),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar"),
):
    """Road IoU (ΣTP/Σ(TP+FP+FN), ignore pixels excluded), mean per-image IoU, precision, recall,
    F1; with probability maps also the KITTI road metrics: MaxF, AP (11-point) and
    precision/recall/FPR/FNR at the MaxF threshold (KITTI devkit definitions). The table starts
    with a '#' line naming the folder and the number of frames scored and, with MaxF, ends with a
    '#' note: IoU and F1 score the masks (P >= 0.5), MaxF the best threshold of P. --json prints
    the metrics alone. Labels in which road covers none or nearly all of the labelled pixels, or
    lies mostly in the frames' upper half, are a warning on stderr (the label format probably does
    not fit them). It scores the frames the folder's last model wrote (predict.json, kept by
    'vctrain predict'), and says how many masks of another model's run it left out.

    --bev scores the same frames again on a metric grid of the road plane (0.05 m cells over
    x -10..10 m, z 6..46 m by default), where every cell is the same area of road: the KITTI road
    benchmark's BEV evaluation (MaxF, AP, PRE, REC, FPR, FNR, its threshold sweep) with KITTI
    calibration files (exactly the devkit's transform2BEV), the same metrics in the BEV of any
    other --camera, each frame at the pose 'vctrain predict --bev' gave it (kept in predict.json:
    its road VP by default, the rule of predict --bev and vcprep bev; the camera's nominal pose
    where none is kept, or with --within none), said on stderr. Cells the camera does not see are
    left out. A folder holding several predict runs' frames: --run N scores one.

    \b
    Example:
      vctrain eval preds/camvid_val --labels data/camvid/valannot --label-format camvid
      vctrain eval preds/kitti --labels data/kitti/gt_image_2 --label-format kitti --json
      vctrain eval preds/kitti --labels data/kitti/gt_image_2 --label-format kitti \\
          --bev --camera data/kitti/calib --json   # the road benchmark's BEV figures under "bev"
    """
    from vcprep.labels import RoadShare, get_label_format

    from ..evaluate import evaluate_folder

    fmt, share, notes, said = get_label_format(label_format), RoadShare(), [], []
    result, n = evaluate_folder(pred_dir, labels, fmt, progress=not quiet, road_share=share, notes=notes,
                                bev=_bev_maps_of(camera, grid_range, res, pred_dir, within, said) if bev else None,
                                run=run)
    for line in said if not quiet else ():  # which BEV poses
        err(line)
    warning = share.warning(fmt, labels)
    for line in notes + ([warning] if warning else []):  # a wrong label format or mixed runs: said under --quiet too
        err(line)
    if as_json:
        emit_json(result)
    else:
        print(f"# {pred_dir}: {count(n, 'frame')} scored against {labels} ({label_format})")
        flat = {**{k: v for k, v in result.items() if k != "bev"},
                **{f"bev_{k}": v for k, v in result.get("bev", {}).items()}}
        for k, v in flat.items():
            print(f"{k:<16} {v:.4f}")
        if "maxf" in result:
            print(MAXF_NOTE)
    if not quiet:
        err(f"{pred_dir}: {count(n, 'image')} evaluated")


def _bev_maps_of(camera: Optional[str], grid_range: Optional[str], res: float, pred_dir: Path, within: str,
                 notes: list):
    """--bev: a frame's stem and size -> its BEV maps (:func:`vcprep.bev.bev_maps`) through --camera, at
    the pose predict --bev kept for it (``within`` 'auto') or the camera's nominal pose; which, said in ``notes``."""
    from vcprep.bev import BevSource, bev_maps, parse_range
    from vcprep.errors import InputError, one_of

    from ..evaluate import recorded_poses
    from ..predict.bev import poses_rule

    if camera is None:
        raise InputError("--bev needs the frames' camera", None, "add --camera (a preset, a camera file, or the "
                         "folder of per-frame calibration files, e.g. KITTI's calib/)")
    if within not in ("auto", "none"):
        raise InputError(f"--within '{within}'", None, one_of(within, ("auto", "none")))
    grid, source = parse_range(grid_range, res), BevSource.from_spec(camera)
    poses = recorded_poses(Path(pred_dir)) if within == "auto" and not source.calibrated else {}
    notes.append(f"{pred_dir}: {poses_rule(poses, source.calibrated, within)}")

    def maps(stem: str, size):
        pose = poses.get(stem) or poses.get(stem.rpartition("/")[2]) or {}
        vp = tuple(pose["vp"]) if pose.get("source") == "vp" and pose.get("vp") else None
        return bev_maps(source.view(Path(stem + ".png"), size, vp, pose.get("vp_status") if vp else None), grid, stem)

    return maps
