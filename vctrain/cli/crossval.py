"""``vctrain crossval``: a cross-camera study from a study file (:func:`vctrain.study.run_study`)."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from vcprep.cliutil import emit_json, err

from ..study.spec import CONDITIONS
from .common import app


@app.command("crossval")
def crossval_cmd(
    study: Path = typer.Argument(..., help="study YAML: datasets (camera, label format, role, train/test images and "
                                           "labels, optional VPs) and settings; schema in docs/studies.md"),
    out: Path = typer.Option(..., "--out", "-o", help="study folder (created; an existing one is resumed)"),
    conditions: Optional[str] = typer.Option(None, "--conditions",
                                             help=f"comma-separated subset of {','.join(CONDITIONS)} (default: "
                                                  "the study file's, else the first five)"),
    heldout: Optional[str] = typer.Option(None, "--heldout", help="comma-separated datasets to evaluate (default: "
                                                                   "every dataset of role both or test)"),
    epochs: Optional[int] = typer.Option(None, "--epochs", "-e", min=1, help="override the study's training epochs"),
    seed: Optional[int] = typer.Option(None, "--seed", help="override the study's training seed (one study folder "
                                                            "per seed)"),
    jobs: int = typer.Option(1, "--jobs", "-j", min=1, help="worker processes for building stores"),
    as_json: bool = typer.Option(False, "--json", help="print {condition: mean road IoU over the evaluated datasets} "
                                                        "as one JSON object instead of the table"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bars or run lines on stderr"),
):
    """Cross-camera study: for each condition, hold out each dataset of role 'both' in turn (train
    on the other trainable datasets) and, if there are datasets of role 'test', train once on every
    trainable dataset and test on each of them; road IoU on the evaluated dataset's test images in
    its own camera ("will my model work on camera X?": give camera X's labelled frames role test).

    Conditions: resize (baseline: images resized), between (virtual camera, average pose),
    within (plus each image's estimated VP), within-gt (the study's given VPs), zero (within with
    zero padding instead of projective completion), prior (no training: the training datasets'
    geometric prior, p_g >= 0.5), adapt (the within model adapted to the evaluated dataset's
    unlabelled images with that prior's tri-mask), adapt-fuse (as adapt, the prior fused with the
    model's own prediction), adapt-self (as adapt, the model's own prediction alone: the control for
    what the prior adds), average (within's and resize's probabilities averaged), resize-vp (resize
    plus the VP channel: each frame's own estimated road VP as a 4th input), mixed (one network
    trained on both views, within and resized, the two averaged), resize-rays (resize plus each
    pixel's ray angles from its VP and focal length); prior, the adapt conditions, average,
    resize-vp, mixed and resize-rays are not among the defaults. Prints the
    table (rows: evaluated dataset and mean; columns: conditions; road IoU in %) and writes
    OUT/table.md, table.csv, results.jsonl,
    summary.json and per-run logs under OUT/runs. Training settings the study does not give are
    vctrain fit's defaults. Finished runs are not redone: run the same command again to resume.

    \b
    Example:
      vctrain crossval study.yaml --out studies/cams
      vctrain crossval study.yaml --out studies/cams --conditions resize,within --epochs 5
      vctrain crossval study.yaml --out studies/cams --json | tail -n 1
      vctrain crossval study.yaml --out studies/seed1 --seed 1
    """
    from ..report import format_table, summary_of
    from ..study.spec import check_conditions, evaluated_datasets, load_study
    from ..study.execute import run_study

    st = load_study(study)
    conds = check_conditions([c.strip() for c in conditions.split(",") if c.strip()]) if conditions else st.conditions
    held = evaluated_datasets(st, [h.strip() for h in heldout.split(",") if h.strip()] if heldout else None)
    overrides = {k: v for k, v in (("epochs", epochs), ("seed", seed)) if v is not None}
    rows = run_study(st, out, conds, held, progress=not quiet, jobs=jobs, train_overrides=overrides,
                     say=(lambda s: None) if quiet else err)
    if as_json:
        emit_json(summary_of(rows, conds))
    else:
        print(format_table(rows, held, conds), end="")
