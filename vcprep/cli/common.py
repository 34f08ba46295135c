"""What the ``vcprep`` commands share: the Typer apps, help texts, and the steps several commands
take alike (a camera from ``--camera``, image arguments, the labels check, the end of a store
build). Commands live in one module per group (:mod:`vcprep.cli`)."""
from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import List

import typer

from vcprep import __version__
from ..camera.pinhole import PRESETS
from ..camera.spec import camera_from_spec
from ..camera.estimate import estimated_line  # noqa: F401 (the commands' name for it)
from ..cliutil import count, ensure_parent, err
from ..dataset import collect_images
from ..errors import InputError, StoreError
from ..io.images import write_png
from ..labels import LABEL_FORMAT_HELP, LABEL_FORMATS

app = typer.Typer(rich_markup_mode=None, pretty_exceptions_enable=False, add_completion=False, no_args_is_help=True,
                  help="Reproject road images from any camera into one standard virtual camera (VCSeg).\n\n"
                       "Add --debug to any command to see a traceback on error.")
camera_app = typer.Typer(rich_markup_mode=None, no_args_is_help=True,
                         help="Camera models: show one, design a virtual camera, estimate one from its frames, "
                              "find the own vehicle's rows (ego).")
store_app = typer.Typer(rich_markup_mode=None, no_args_is_help=True,
                        help="Virtual-camera image stores: show the items, verify, info (counts, parameters, disk "
                             "use), merge shard part files.")
figure_app = typer.Typer(rich_markup_mode=None, no_args_is_help=True, help="Figures (PNG) a person can look at.")
app.add_typer(camera_app, name="camera")
app.add_typer(store_app, name="store")
app.add_typer(figure_app, name="figure")

COMPLETE_HELP = ("fill uncovered virtual pixels: projective (paper §4.3: rays from the VP), zero (image 0, label "
                 "not road), replicate (nearest covered pixel) or none (image 0, label ignore)")
CAMERA_HELP = (f"camera preset ({', '.join(PRESETS)}; write preset:NAME where a file or folder of that name exists: "
               "a bare name that is both is an error) or file (.yaml camera, .txt KITTI calib, .json Cityscapes)")
ESTIMATE_HELP = ", or 'estimate': estimated from these frames (as 'vcprep camera estimate' does)"
FRAMES_HELP = (CAMERA_HELP + ", or a folder of per-frame calibration files matched to the images by stem (KITTI "
               "calib/<stem>.txt, Cityscapes camera/.../<stem>_camera.json): each image gets its own camera and pose")
WITHIN_HELP = ("within-camera correction: 'none' (camera's average pose), 'estimate' (detect each image's road "
               "VP) or a CSV file 'id,u,v' of known VPs in source pixels")
JOBS_HELP = "worker processes (default: one per core); results are identical for any number"
SHARD_HELP = ("build only shard K of N (K = 1..N; items split by a hash of their id), recording into the store's "
              "shard part file: N machines can build one store on a shared file system; see 'vcprep store merge'")
KEEP_GOING_HELP = ("skip bad items instead of stopping at the first: each is reported, the rest is built, "
                   "and the exit status is 1 at the end")
SMOOTH_HELP = ("temporal smoothing of estimated VPs: median over N frames either side within a sequence "
               "(sequence = file name up to the first '_', frames in name order); 0 = off")


def _version(value: bool):
    if value:
        print(f"vcprep {__version__}")
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", callback=_version, is_eager=True, help="Print the version.")):
    pass


def save_figure(out: Path, fig) -> None:
    """Write a figure PNG atomically and print its path (stdout is data)."""
    write_png(ensure_parent(out), fig, level=3)
    print(out)


def camera_for(spec: str, sample_image: Path | None = None, per_frame: bool = True,
               frames: "list[Path] | None" = None, quiet: bool = False, needed: bool = True):
    """``--camera`` (:func:`vcprep.camera.sources.camera_from_spec`): an estimated camera said on
    stderr unless ``quiet``."""
    return camera_from_spec(spec, sample_image, per_frame, frames, needed, None if quiet else err)


def image_files(paths: List[Path], unique: "tuple[str, str] | None" = None) -> list[Path]:
    """IMAGES arguments: files as given, folders expanded to their images (recursively, sorted);
    ``unique``: as :func:`vcprep.dataset.collect_images` (None: one stem may repeat)."""
    return [j.image for j in collect_images(paths, unique=unique, missing="image file not found")]


def check_label_format(labels: Path | None, label_format: str | None) -> None:
    """--labels needs --label-format."""
    if labels is not None and label_format is None:
        raise InputError("--labels given without --label-format", labels, f"add --label-format ({', '.join(LABEL_FORMATS)})")


def vp_counts(results) -> str:
    """'3 accepted, 1 fallback': the VP statuses of ``results``."""
    c = Counter(r.status for r in results)
    return ", ".join(f"{c[k]} {k}" for k in ("accepted", "fallback", "given") if c[k])


def finish(out: Path, summary, quiet: bool, extra: str = "", verb: str = "built") -> None:
    """End of a store build: failures (always), summary and notes (unless quiet), the path on
    stdout; exit 1 via StoreError if items failed (--keep-going)."""
    for msg in summary.errors:
        err(f"failed: {msg}")
    if not quiet:
        err(f"{out}: {summary.line(extra).replace('built', verb, 1)}")
        _notes(summary)
    print(out)
    if summary.failed:
        raise StoreError(f"{len(summary.failed)} of {count(summary.total, 'item')} failed (listed above)", out,
                         "fix or remove those files and run the same command again; finished items are kept")


def _notes(summary, limit: int = 10) -> None:
    """Per-item remarks on stderr, each with its verdict and what to do (e.g. an item completed
    far from its VP outside the covered region), the first ``limit``."""
    for n in summary.notes[:limit]:
        err(f"warning: {n}")
    if len(summary.notes) > limit:
        err(f"warning: ... and {len(summary.notes) - limit} more (see completion_vp_inside in the records)")
