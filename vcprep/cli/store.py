"""Commands that build and read stores: ``warp``, ``complete``, ``store show|verify|info|merge``, ``backproject``, ``prior``."""
from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import Any, List, Optional

import typer
from tqdm import tqdm

from ..warp.backproject import backproject_folder
from ..store.build import WarpSettings, say_on_stderr, warp_dataset
from ..vp.cache import VP_CACHE, VPCache
from ..vp.poses import frame_poses
from ..store.layout import prepare_store_dir
from ..camera.pinhole import Camera
from ..camera.sources import load_camera
from ..camera.files import camera_from_dict
from ..camera.virtual import (DESIGN_ABOVE, DESIGN_PAN_RANGE, DESIGN_TILT_RANGE, STORE_PIXELS, design_virtual_camera,
                              scale_for_pixels)
from ..io.images import image_size
from ..camera.estimate import estimate_camera, estimate_to_yaml
from ..cliutil import Interrupted, check_data_folders, count, emit_json, ensure_parent, err
from ..dataset import list_dataset
from ..errors import InputError, StoreError
from ..io.images import write_bytes_atomic
from ..labels import get_label_format
from ..store.parallel import default_jobs
from ..prior import compute_prior, open_stores, prior_meta, write_prior
from ..store.layout import Shard, Store
from ..store.trained import is_trained_source, trained_virtual
from ..store.check import merge_store, store_info, verify_and_repair, verify_store
from ..store.complete import CompleteSettings, complete_store
from ..vp.reliability import VPRule
from .common import (COMPLETE_HELP, FRAMES_HELP, JOBS_HELP, KEEP_GOING_HELP, LABEL_FORMAT_HELP, SHARD_HELP,
                     SMOOTH_HELP, WITHIN_HELP, app, camera_for, check_label_format, estimated_line, finish, store_app,
                     vp_counts)


DESIGN_NAME = "design"  # the name of the virtual camera `vcprep warp` designs (no --virtual)
DESIGN = (f"pan +/-{DESIGN_PAN_RANGE:g} deg, tilt +/-{DESIGN_TILT_RANGE:g} deg, {DESIGN_ABOVE:g} deg above the horizon, "
          f"{STORE_PIXELS:,} px")
VIRTUAL_HELP = ("virtual camera: 'design' (designed from --camera: the measured design), a preset or a YAML file "
                "(e.g. from 'vcprep camera design CAM1 CAM2 ...' for several cameras in one store), or a model "
                "(.pt) or store: the virtual camera and scale it was trained in; "
                "default: the store's own when OUT is a store, else 'design'")
SCALE_HELP = (f"store scale of the full virtual camera (0.125: the 'virtual' preset at 688x350); default: the store's "
              f"own, else the scale giving {STORE_PIXELS:,} pixels (480x360's)")


WARP_CAMERA_OPT = typer.Option(..., "--camera", "-c", help=FRAMES_HELP + ", or 'estimate': estimated from these "
                               "frames (as 'vcprep camera estimate' does; written to STORE/camera.estimated.yaml)")
WARP_IMAGES_OPT = typer.Option(..., "--images", "-i", help="folder of source images (subfolders included)")
WARP_OUT_OPT = typer.Option(..., "--out", "-o", help="store directory (created, or updated in place)")
WARP_LABELS_OPT = typer.Option(None, "--labels", "-l", help="folder of label images, a tree mirroring --images (e.g. "
                               "gtFine/train for leftImg8bit/train)")
WARP_LABEL_FORMAT_OPT = typer.Option(None, "--label-format", "-f", help=LABEL_FORMAT_HELP)
WARP_VIRTUAL_OPT = typer.Option(None, "--virtual", help=VIRTUAL_HELP)
WARP_SCALE_OPT = typer.Option(None, "--scale", "-s", help=SCALE_HELP)
WARP_ID_PREFIX_OPT = typer.Option("", "--id-prefix", help="prefix for item ids (keeps datasets apart in one store)")
WARP_COMPLETE_OPT = typer.Option("projective", "--complete", help=COMPLETE_HELP)
WARP_WITHIN_OPT = typer.Option(None, "--within", help=WITHIN_HELP + "; default: 'estimate' for one camera, 'none' for "
                               "per-frame calibration (each frame's exact pose)")
WARP_VP_SMOOTH_OPT = typer.Option(0, "--vp-smooth", min=0, help=SMOOTH_HELP)
WARP_JOBS_OPT = typer.Option(None, "--jobs", "-j", min=1, help=JOBS_HELP)
WARP_SHARD_OPT = typer.Option(None, "--shard", help=SHARD_HELP)
WARP_KEEP_GOING_OPT = typer.Option(False, "--keep-going", "-k", help=KEEP_GOING_HELP)
WARP_QUIET_OPT = typer.Option(False, "--quiet", "-q", help="no progress bar or summary on stderr")


@app.command("warp")
def warp_cmd(
    camera: str = WARP_CAMERA_OPT, images: Path = WARP_IMAGES_OPT, out: Path = WARP_OUT_OPT,
    labels: Optional[Path] = WARP_LABELS_OPT, label_format: Optional[str] = WARP_LABEL_FORMAT_OPT,
    virtual: Optional[str] = WARP_VIRTUAL_OPT, scale: Optional[float] = WARP_SCALE_OPT,
    id_prefix: str = WARP_ID_PREFIX_OPT, complete: str = WARP_COMPLETE_OPT, within: Optional[str] = WARP_WITHIN_OPT,
    vp_smooth: int = WARP_VP_SMOOTH_OPT, jobs: Optional[int] = WARP_JOBS_OPT, shard: Optional[str] = WARP_SHARD_OPT,
    keep_going: bool = WARP_KEEP_GOING_OPT, quiet: bool = WARP_QUIET_OPT,
):
    """Warp a folder of images (and labels) from CAMERA into the virtual camera store OUT.

    With no --virtual, --scale or --within this is the measured design, what 'vctrain crossval'
    trains on for one camera: a virtual camera designed from CAMERA (as 'vcprep camera design
    CAMERA --pan-range 10 --tilt-range 5 --above 8' does), stores of 172,800 pixels (480x360's),
    each image's pose from its own road vanishing point (--within estimate). A store that exists
    keeps its own virtual camera and scale, so another camera's frames join it.

    Images are resampled bilinearly, labels by nearest neighbour and stored as 0 = not road,
    1 = road, 255 = ignore. Virtual pixels no source pixel covers are filled in the same remap
    by --complete (default projective, the paper's §4.3; 'none' leaves image 0 / label ignore;
    the valid/ mask always marks the covered pixels). Re-running with unchanged inputs does no work; a changed image,
    label, camera or parameter redoes exactly the affected items. Prints the store path.

    A camera YAML with 'ego_rows: N' (the bottom N rows of every image, at its image_size,
    show the rig's own vehicle) cuts those rows off before warping, an exact bottom crop: they
    never reach the store (completed like any uncovered pixel; labels ignore without
    completion); records keep the full size and ego_rows, for back-projection.

    With --within, each image's own pan and tilt come from its road vanishing point
    (within-camera correction): 'estimate' detects it (see 'vcprep vp'), FILE reads a CSV
    'id,u,v' of known VPs (source pixels); the record gets vp, vp_status, pan_deg, tilt_deg.

    Items are built by --jobs worker processes; a bad item stops the build (items finished
    so far are kept) unless --keep-going. Ctrl-C stops after the items in flight; a killed
    build loses only those: run the same command again to resume.

    \b
    Example:
      vcprep warp --camera camvid --images data/camvid/train \\
          --labels data/camvid/trainannot --label-format camvid --out stores/camvid
      vcprep warp --camera camvid --images data/camvid/train --out stores/camvid --shard 2/8
      (with --shard, give --within a CSV from 'vcprep vp', or every shard estimates every VP)
      vcprep warp --camera camvid --images data/camvid/val --out stores/paper \\
          --virtual virtual --scale 0.125 --within none   # the paper's 688x350 store
      vcprep warp --camera camvid --images data/camvid/val --out stores/val --within vps.csv
      vcprep warp --camera estimate --images mine/images --labels mine/labels --label-format camvid \\
          --virtual models/vc.pt --out stores/tune   # into the virtual camera a model was trained in
      vcprep warp --camera kitti/training/calib --images kitti/training/image_2 \\
          --labels kitti/training/gt_image_2 --label-format kitti --out stores/kitti   # per-frame calibration
      vcprep warp --camera cityscapes/camera/train --images cityscapes/leftImg8bit/train \\
          --labels cityscapes/gtFine/train --label-format cityscapes --out stores/cs   # nested city folders
    """
    part = Shard.parse(shard) if shard else None
    check_label_format(labels, label_format)
    fmt = get_label_format(label_format) if label_format else None
    check_data_folders(images, labels)
    items = list_dataset(images, labels, fmt, id_prefix)
    cam, estimate = _warp_camera(camera, items, fmt, quiet)
    within = _within_rule(within, cam, camera)
    virt, scale, design = _warp_virtual(virtual, scale, cam, items, out)
    if fmt is not None:
        _check_labels(items, fmt, labels)
    # VPs over all frames even for one shard: the fallback VP and smoothing depend on the whole run
    poses, vps = _within_poses(items, cam, within, vp_smooth, id_prefix, quiet, fmt, bool(design), out)
    settings = WarpSettings(camera=cam, virtual=virt, scale=scale, label_format=fmt, completion=complete, poses=poses,
                            workers=jobs or default_jobs(), shard=part, keep_going=keep_going, progress=not quiet)
    store, summary = warp_dataset(items, out, settings)
    _say_other_camera(out, summary)
    _keep_estimate(out, estimate, quiet)
    finish(out, summary, quiet, f" (store {store.store_size[0]}x{store.store_size[1]}{design}"
                                 f"{f', shard {part}' if part else ''}{vps})")


def _say_other_camera(out: Path, summary) -> None:
    """Frames of another camera warped into a store that held frames (issue 80: a day's frames warped
    into another day's training store by mistake): both cameras named, on stderr even under --quiet."""
    new = [c for c in summary.cameras if c not in summary.held_cameras]
    if summary.held and new:
        err(f"warning: {out}: the store held {count(summary.held, 'item')} of camera {', '.join(summary.held_cameras)}; "
            f"these {count(summary.total, 'frame')} are of camera {', '.join(new)}, and it now holds both (a store of "
            "several cameras may; if they were meant for a store of their own, give another --out)")


def _keep_estimate(out: Path, estimate, quiet: bool) -> None:
    """A camera estimated from the frames is kept beside the store (``camera.estimated.yaml``) and said."""
    if estimate is None:
        return
    write_bytes_atomic(out / "camera.estimated.yaml", estimate_to_yaml(estimate).encode())
    if not quiet:
        err(estimated_line(estimate, f"the frames ({out / 'camera.estimated.yaml'})"))


def _check_labels(items: list, fmt, labels: Path, samples: int = 48) -> None:
    """Warn (stderr, even under --quiet) when road in up to ``samples`` labels spread over the set
    makes no sense under ``fmt`` (:class:`vcprep.labels.RoadShare`); a label that cannot be read or
    decoded is left to the build, which says so."""
    import numpy as np

    from ..errors import VCError
    from ..io.images import read_image
    from ..labels import RoadShare, decode_label

    labelled = [j for j in items if j.label is not None]
    share = RoadShare()
    for k in sorted({int(round(k)) for k in np.linspace(0, len(labelled) - 1, min(samples, len(labelled)))}):
        try:
            share.add(decode_label(read_image(labelled[k].label, label=True).array, fmt, labelled[k].label))
        except VCError:
            continue
    warning = share.warning(fmt, labels)
    if warning:
        err(warning)


def _warp_camera(camera: str, items: list, fmt, quiet: bool):
    """(camera, its estimate or None) of ``vcprep warp --camera``: 'estimate' estimates it from
    the frames (and the own vehicle from their labels, with >= 5), said on stderr."""
    if camera != "estimate":
        return camera_for(camera, items[0].image), None
    if not quiet:
        err(f"estimating the camera from {count(len(items), 'frame')}")
    est_labels = [j.label for j in items if j.label is not None]
    estimate = estimate_camera([j.image for j in items], name="estimated", ids=[j.id for j in items],
                               labels=est_labels if len(est_labels) >= 5 else None, label_format=fmt)
    return estimate.camera, estimate


def _within_rule(within: Optional[str], cam, camera: str) -> str:
    """--within, or its default: 'estimate' for one camera, 'none' for per-frame calibration (which
    refuses any other)."""
    if within is None:
        return "estimate" if isinstance(cam, Camera) else "none"
    if not isinstance(cam, Camera) and within != "none":
        raise InputError("--within needs one camera; a per-frame calibration folder already gives every frame its "
                         "exact pose", camera, "drop --within, or give one camera file or preset")
    return within


def _warp_virtual(virtual: Optional[str], scale: Optional[float], cam, items: list,
                  out: Path) -> tuple[Camera, float, str]:
    """(virtual camera, store scale, what the summary says of a designed one, else '') of ``vcprep
    warp``: --virtual (a preset or file; 'design': designed from the frames' camera as :data:`DESIGN`
    says; a model checkpoint or a store: the one it was trained in, at its scale); none given, the
    store's own when OUT is one, else the design. --scale, else the store's (the model's), else the
    scale of :data:`STORE_PIXELS` pixels."""
    if virtual is None and (out / "store.json").is_file():
        store = Store.open(out)
        virt = camera_from_dict(store.params["virtual"], out / "store.json")
        own = ", the store's designed virtual camera" if virt.name == DESIGN_NAME else ""
        return virt, float(store.scale if scale is None else scale), own
    if virtual in (None, "design"):
        one = cam if isinstance(cam, Camera) else cam.for_image(items[0].image, image_size(items[0].image))
        virt = design_virtual_camera([one], DESIGN_PAN_RANGE, DESIGN_TILT_RANGE, name=DESIGN_NAME,
                                     above=DESIGN_ABOVE).camera
        return (virt, scale_for_pixels(virt) if scale is None else float(scale),
                f", virtual camera designed from {one.name}: {DESIGN}")
    if is_trained_source(virtual):  # a model's (or a store's) own virtual camera and scale: fine-tuning's data
        virt, own_scale = trained_virtual(virtual)
        designed = f", designed from its training camera: {DESIGN}" if virt.name == DESIGN_NAME else ""
        return (virt, own_scale if scale is None else float(scale),
                f", the virtual camera of {Path(virtual).name}{designed}" if designed else "")
    virt = load_camera(virtual)
    return virt, scale_for_pixels(virt) if scale is None else float(scale), ""


def _within_poses(jobs, cam: Camera, within: str, smooth: int, id_prefix: str, quiet: bool, fmt=None,
                  designed: bool = False, out: Path | None = None) -> tuple[Any, str]:
    """(the ``poses`` mapping of :class:`vcprep.store.build.WarpSettings` from ``--within``, None for
    'none'; the summary's words on the VPs); ``designed``: VPs accepted within the design's pose
    ranges (as a crossval study's). Estimated VPs are kept in the store's folder ``out`` as they
    are found (:class:`vcprep.vp.cache.VPCache`): a run stopped part way does not find them again."""
    if within == "none":
        if smooth:
            raise InputError("--vp-smooth needs --within estimate", None, "add --within estimate or drop --vp-smooth")
        return None, ""

    if within != "estimate" and smooth:
        raise InputError("--vp-smooth applies to estimated VPs only", within, "use --within estimate")
    bar = tqdm(total=len(jobs), desc="vp", unit="img", disable=True if quiet or within != "estimate" else None, leave=False)
    cache = None
    try:
        # IDD's file names repeat from drive to drive: its frames' sequences are their folders, as its item ids say
        seqs = "folder" if fmt is not None and fmt.drive_in_id else "name"
        rule = (VPRule(DESIGN_PAN_RANGE, DESIGN_TILT_RANGE, smooth=smooth, sequences=seqs) if designed
                else VPRule(smooth=smooth, sequences=seqs))
        if within == "estimate" and out is not None:
            prepare_store_dir(out)  # (a new folder, a store or a build's: never a foreign folder)
            cache = VPCache(out / VP_CACHE)
        poses, results = frame_poses(jobs, cam, within, rule, id_prefix, lambda i: bar.update(), cache=cache)
    except KeyboardInterrupt:
        if cache is None:
            raise
        raise Interrupted(f"while finding road VPs, before warping; the {len(cache)} found so far are kept in "
                          f"{out / VP_CACHE}") from None
    finally:
        bar.close()
    return poses, f"; road VPs: {vp_counts(results)}"


@app.command("complete")
def complete_cmd(store: Path = typer.Argument(..., help="store directory built by 'vcprep warp'"),
                 method: str = typer.Option("projective", "--method", "-m", help=COMPLETE_HELP),
                 jobs: Optional[int] = typer.Option(None, "--jobs", "-j", min=1, help=JOBS_HELP),
                 shard: Optional[str] = typer.Option(None, "--shard", help=SHARD_HELP),
                 keep_going: bool = typer.Option(False, "--keep-going", "-k", help=KEEP_GOING_HELP),
                 quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar or summary on stderr")):
    """Complete an already-warped store in place: fill the pixels no source pixel covers.

    Each item is rebuilt from its recorded source image and label (which must be unchanged)
    as one warp + completion remap, so the result is identical to 'vcprep warp --complete
    METHOD'. Items already completed with METHOD are skipped. Prints the store path.

    \b
    Example:
      vcprep warp --camera camvid --images data/camvid/train --out stores/camvid --complete none
      vcprep complete stores/camvid --method projective
    """
    part = Shard.parse(shard) if shard else None
    st, summary = complete_store(store, CompleteSettings(method, workers=jobs or default_jobs(), shard=part,
                                                         keep_going=keep_going, progress=not quiet))
    finish(store, summary, quiet, f" ({method}{f', shard {part}' if part else ''})", verb="completed")


@store_app.command("show")
def store_show(store: Path = typer.Argument(..., help="store directory"),
               as_json: bool = typer.Option(False, "--json", help="one JSON item record per line")):
    """List the items of a store (id, camera, source), or their full records with --json.

    \b
    Example:
      vcprep store show stores/camvid --json | head -1
    """
    st = Store.open(store)
    for rec in st:
        if as_json:
            emit_json(rec)
        else:
            print(f"{rec['id']}\t{rec['camera']}\t{rec['source']}")
    if not as_json:
        err(f"{store}: {count(len(st), 'item')}, {st.store_size[0]}x{st.store_size[1]} at scale {st.scale:g}")


@store_app.command("verify")
def store_verify(store: Path = typer.Argument(..., help="store directory"),
                 sources: bool = typer.Option(True, "--sources/--no-sources",
                                              help="also check that source images and labels still match their hashes"),
                 as_json: bool = typer.Option(False, "--json", help="one JSON object per problem"),
                 repair: bool = typer.Option(False, "--repair", help="drop the records and files of items with bad "
                                             "stored files and delete orphans, so that re-running the build redoes "
                                             "them (waits for a running build: it holds the store lock)"),
                 strict: bool = typer.Option(False, "--strict", help="also exit 1 on orphan or temp files (what an "
                                             "interrupted build leaves; the next build removes them)"),
                 jobs: Optional[int] = typer.Option(None, "--jobs", "-j", min=1, help=JOBS_HELP),
                 quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar or summary on stderr")):
    """Check a store: every recorded PNG exists, decodes, has the store size, allowed values
    and its recorded SHA-256; sources still hash as recorded; no orphan (unrecorded) PNGs or
    temp files. Prints one line per problem (id, kind, file, detail; --json: objects) and
    exits 1 on damage: a record whose file is missing or does not match (or whose source
    changed). Orphan and temp files, left by an interrupted build (kill -9), are listed with
    exit 0 (--strict: exit 1); the next build or 'vcprep store merge' removes them. A build
    skips items whose files exist, so to redo items with bad files run --repair first, then
    the build.

    \b
    Example:
      vcprep store verify stores/camvid
      vcprep store verify stores/camvid --strict --quiet   # exit 1 on any problem, leftovers included
      vcprep store verify stores/camvid --no-sources --json | jq -r .id | sort -u
      vcprep store verify stores/camvid --repair; vcprep warp ... --out stores/camvid
    """
    dropped, removed = [], 0
    if repair:  # under the store lock: waits for a running build, whose files in flight are no orphans
        report, dropped, removed = verify_and_repair(store, sources, jobs or default_jobs(), not quiet,
                                                     on_wait=None if quiet else say_on_stderr)
    else:
        report = verify_store(store, check_sources=sources, workers=jobs or default_jobs(), progress=not quiet)
    for p in report.problems:
        if as_json:
            emit_json(asdict(p))
        else:
            print(p.line())
    if not quiet:
        err(f"{store}: {report.summary()}")
    repaired = f"repaired: dropped {count(len(dropped), 'item')}, deleted {count(removed, 'file')}" if repair else ""
    if not report.failed(strict):
        if repaired and report.problems and not quiet:
            err(f"{store}: {repaired}")
        return
    bad = report.bad_items
    named = ", ".join(bad[:10]) + (f" and {len(bad) - 10} more" if len(bad) > 10 else "")
    if repaired:
        fix = f"{repaired}; re-run the build command to redo them" if bad else repaired
    elif bad:
        fix = "run 'vcprep store verify --repair STORE', then the build command again, to redo them"
    else:
        fix = "run the build command again or 'vcprep store merge STORE': either removes them"
    raise StoreError(f"{count(len(bad), 'bad item')}{': ' + named if bad else ''}; "
                     f"{count(len(report.orphans), 'orphan or temp file')}", store, fix)


@store_app.command("info")
def store_info_cmd(store: Path = typer.Argument(..., help="store directory"),
                   as_json: bool = typer.Option(False, "--json", help="one JSON object")):
    """Counts, parameters and disk use of a store.

    \b
    Example:
      vcprep store info stores/camvid
      vcprep store info stores/camvid --json | jq .disk_bytes
    """
    info = store_info(store)
    if as_json:
        emit_json(info)
        return
    mb = lambda b: f"{b / 1e6:.1f} MB"
    print(f"store\t{info['store']}")
    print(f"parameters\tvirtual {info['virtual']} at scale {info['scale']:g} -> "
          f"{info['store_size'][0]}x{info['store_size'][1]} ({info['created_by']}, format v{info['version']})")
    print(f"items\t{info['items']} ({info['with_labels']} with labels)")
    for key in ("cameras", "completion", "vp_status", "label_format", "tool_version"):
        print(f"{key}\t" + ", ".join(f"{k} {v}" for k, v in info[key].items()))
    print("disk\t" + ", ".join(f"{k} {v['files']} files {mb(v['bytes'])}" for k, v in info["disk"].items())
          + f"; total {mb(info['disk_bytes'])}")
    if info["pending_parts"]:
        print(f"pending\t{', '.join(info['pending_parts'])} (fold with 'vcprep store merge')")


@store_app.command("merge")
def store_merge(store: Path = typer.Argument(..., help="store directory"),
                quiet: bool = typer.Option(False, "--quiet", "-q", help="no summary on stderr")):
    """Fold the shard part files of a store (built with 'warp --shard K/N') into its
    manifest.jsonl and remove temp files and orphans of interrupted builds. Run it once every
    shard has finished (it waits for running builds: it holds the store lock). The store is
    readable before (parts are read too); merging makes it one file.

    \b
    Example:
      vcprep warp -c camvid -i data/camvid/train -o stores/camvid --shard 1/2 &
      vcprep warp -c camvid -i data/camvid/train -o stores/camvid --shard 2/2; wait
      vcprep store merge stores/camvid
    """
    st, n = merge_store(store, on_wait=None if quiet else say_on_stderr)
    if not quiet:
        err(f"{store}: merged {count(n, 'part file')}; {count(len(st), 'item')}")
    print(store)


@app.command("backproject")
def backproject_cmd(store: Path = typer.Argument(..., help="store the masks belong to"),
                    masks: Path = typer.Argument(..., help="folder of virtual-domain PNGs named <id>.png"),
                    out: Path = typer.Option(..., "--out", "-o", help="output folder (created)"),
                    kind: str = typer.Option("mask", help="'mask' (nearest) or 'prob' (bilinear)"),
                    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar")):
    """Map virtual-domain masks or probability maps back to each item's original camera,
    exactly inverting its H. Writes OUT/<id>.png at the source image size; source pixels
    outside the virtual image get 0. The ego_rows of an item whose camera sees its own vehicle
    get what the store holds there (the completion of the visible scene), like every pixel.

    \b
    Example:
      vcprep backproject stores/camvid preds/virtual --out preds/camvid --kind prob
    """
    n = backproject_folder(store, masks, out, kind=kind, progress=not quiet)
    if not quiet:
        err(f"{out}: {count(n, 'map')} back-projected")
    print(out)


@app.command("prior")
def prior_cmd(stores: List[Path] = typer.Argument(..., help="labelled stores of one virtual camera and scale"),
              out: Path = typer.Option(..., "--out", "-o", help="prior.npy (float32 p_g) or prior.png (uint8 round(255 p_g))"),
              quiet: bool = typer.Option(False, "--quiet", "-q", help="no summary on stderr")):
    """Geometric road prior (paper §4.5): p_g(x, y) = the mean road label over the stores'
    labelled items in the virtual camera; ignore pixels (255) count in neither the numerator nor
    the denominator; a pixel no item labels gets 0. Writes OUT and OUT.json beside it (virtual
    camera, scale, item counts); prints OUT. Stores of another virtual camera or scale are refused.

    \b
    Example:
      vcprep prior stores/camvid stores/kitti -o prior.npy
      vcprep prior stores/camvid -o prior.png
    """
    opened = open_stores(stores)
    prior, n_unlabelled = compute_prior(opened)
    meta = prior_meta(opened, n_unlabelled)
    write_prior(ensure_parent(out), prior, meta)
    if not quiet:
        w, h = opened[0].store_size
        err(f"{out}: p_g over {count(meta['items'], 'labelled item')} of {count(len(opened), 'store')} ({w}x{h}); "
            f"{count(n_unlabelled, 'pixel')} with no labelled item (set to 0)")
    print(out)
