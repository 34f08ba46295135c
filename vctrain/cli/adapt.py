"""``vctrain adapt``: fine-tune a virtual-camera model on unlabelled target images with surrogate
labels from the geometric prior (:func:`vctrain.adapt.adapt`)."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from vcprep.cliutil import count, ensure_parent, err

from ..training.config import AdaptSettings
from .common import ADAPT, app, path_or_json


@app.command("adapt")
def adapt_cmd(
    checkpoint: Path = typer.Argument(..., help="virtual-camera model written by 'vctrain fit'"),
    images: Path = typer.Option(..., "--images", "-i", help="folder (or file) of UNLABELLED target images"),
    camera: str = typer.Option(..., "--camera", "-c", help="camera of the target images: preset or file (.yaml, "
                                                           "KITTI .txt, Cityscapes .json), or a folder of per-frame "
                                                           "calibration files (every frame its exact pose), or "
                                                           "'estimate' (from these images)"),
    prior: Path = typer.Option(..., "--prior", help="geometric prior written by 'vcprep prior' (.npy or .png) in the "
                                                    "model's virtual camera and scale"),
    out: Path = typer.Option(..., "--out", "-o", help="adapted checkpoint; the latest epoch and the log "
                                                      "beside it (runs/ad.last.pt, runs/ad.log.jsonl)"),
    lo: float = typer.Option(ADAPT.lo, "--lo", help="surrogate 'not road' where the (fused) probability is below this"),
    hi: float = typer.Option(ADAPT.hi, "--hi", help="surrogate 'road' where the (fused) probability is above this"),
    combine: str = typer.Option(ADAPT.combine, "--combine", help="'prior': the prior's tri-mask alone (paper §4.5); 'fuse': "
                                                           "prior and the model's own prediction fused per image "
                                                           "(p_g p_n / (p_g p_n + (1-p_g)(1-p_n))) before the thresholds; "
                                                           "'self': the model's own prediction alone (self-training: "
                                                           "the control for what the prior adds; the prior is checked, "
                                                           "not used)"),
    epochs: int = typer.Option(ADAPT.epochs, "--epochs", "-e", help="fine-tuning epochs"),
    lr: Optional[float] = typer.Option(None, "--lr", help="learning rate (default: a tenth of the model's own)"),
    store: Optional[Path] = typer.Option(None, "--store", help="store for the warped target images and their surrogate "
                                                               "labels (default: beside OUT, runs/ad.store; reused)"),
    within: str = typer.Option("auto", "--within", help="per-image VP correction: auto (as the model was trained), "
                                                         "estimate, a CSV id,u,v, or none"),
    seed: Optional[int] = typer.Option(None, "--seed", help="seed (default: the model's)"),
    device: str = typer.Option("auto", "--device", help="auto, cpu, cuda, cuda:N"),
    as_json: bool = typer.Option(False, "--json", help="print the run summary as one JSON object instead of the path"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar or epoch lines on stderr"),
):
    """Fine-tune a virtual-camera model on unlabelled target images with surrogate labels from
    the geometric prior (paper §4.5, after GeoSeg). The images are warped exactly as the model's
    training store was built (virtual camera, scale, completion, within mode); surrogate labels
    are road where p_g > --hi, not road where p_g < --lo, ignore elsewhere (--combine fuse: the
    model's own prediction fused in first). Training settings are the model's own, for --epochs
    at --lr, without validation. The checkpoint records that it was adapted, from which model,
    with which prior and thresholds. Prints the checkpoint path.

    \b
    Example:
      vcprep prior stores/camvid stores/kitti -o prior.npy
      vctrain adapt runs/vc.pt --images data/qian/train --camera qian --prior prior.npy --out runs/vc_qian.pt
      vctrain adapt runs/vc.pt -i data/qian/train -c qian --prior prior.npy --combine fuse -o runs/fused.pt
    """
    from vcprep.cli import camera_for

    from ..adapt import adapt
    from vcprep.dataset import collect_images

    cam = camera_for(camera, collect_images([images])[0].image, frames=[j.image for j in collect_images([images])],
                     quiet=quiet)
    ensure_parent(out)
    settings = AdaptSettings(lo=lo, hi=hi, combine=combine, epochs=epochs, lr=lr, store=store, within=within,
                             device=device, seed=seed, progress=not quiet)
    summary = adapt(checkpoint, images, cam, prior, out, settings)
    if not quiet:
        sh = summary["adapted"]["label_shares"]
        err(f"{out}: adapted {checkpoint} on {count(len(summary['adapted']['images']), 'image')}, {count(summary['epochs'], 'epoch')} at "
            f"lr {summary['adapted']['lr']:g}; surrogate labels {sh['road']:.1%} road, {sh['not_road']:.1%} not road, "
            f"{sh['ignore']:.1%} ignore")
    path_or_json(out, summary, as_json)
