"""``vcprep``: the command line. Parses, calls the library, prints; nothing else lives here."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from . import __version__
from .camera import PRESETS, Camera, camera_to_yaml, load_camera
from .cliutil import check_data_folders, count, emit_json, ensure_parent, err, run_app
from .errors import InputError
from .labels import LABEL_FORMATS, get_label_format
from .parallel import default_jobs

app = typer.Typer(rich_markup_mode=None, pretty_exceptions_enable=False, add_completion=False, no_args_is_help=True,
                  help="Reproject road images from any camera into one standard virtual camera (VCSeg).\n\n"
                       "Add --debug to any command to see a traceback on error.")
camera_app = typer.Typer(rich_markup_mode=None, no_args_is_help=True, help="Camera models: show and design.")
store_app = typer.Typer(rich_markup_mode=None, no_args_is_help=True, help="Inspect, verify, describe and merge virtual-camera image stores.")
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
    from .imageio import write_png

    write_png(ensure_parent(out), fig, level=3)
    print(out)


def camera_for(spec: str, sample_image: Path | None = None, per_frame: bool = True,
               frames: "list[Path] | None" = None, quiet: bool = False):
    """Load ``spec`` (:func:`vcprep.camera.load_cameras`): calibration files (.txt/.json) carry
    no image size, so it is taken from a frame; a folder is per-frame calibration
    (:class:`~vcprep.camera.FrameCameras`) where ``per_frame``, else an error. ``estimate``:
    the camera estimated from ``frames`` (:mod:`vcprep.camera_estimate`; said on stderr)."""
    from .camera import load_cameras

    if spec == "estimate":
        if frames is None:
            raise InputError("this command cannot estimate a camera", None,
                             "run 'vcprep camera estimate FRAMES -o cam.yaml' and give --camera cam.yaml")
        from .camera_estimate import estimate_camera

        est = estimate_camera(frames, name="estimated")
        if not quiet:
            v = est.values
            err(f"camera ESTIMATED from {count(len(frames), 'frame')}: tilt {v['tilt'].value:g} deg, pan "
                f"{v['pan'].value:g} deg; " + "; ".join(f"assumed {w}" for w in est.warnings)
                + " (write it out with 'vcprep camera estimate')")
        return est.camera
    return load_cameras(spec, sample_image, per_frame=per_frame)


@app.command("cameras")
def cameras_cmd(as_json: bool = typer.Option(False, "--json", help="One JSON object per preset.")):
    """List the built-in camera presets with their fields of view.

    \b
    Example:
      vcprep cameras
      vcprep cameras --json | jq .fov_deg
    """
    if not as_json:
        print(f"{'preset':<12} {'size':>10} {'fx':>7} {'fy':>7} {'height m':>8} {'tilt':>5} {'HFOV':>6} {'VFOV':>6}")
    for cam in PRESETS.values():
        hf, vf = cam.fov_deg()
        if as_json:
            emit_json({**cam.to_dict(), "fov_deg": [round(hf, 2), round(vf, 2)]})
        else:
            print(f"{cam.name:<12} {cam.size[0]:>5}x{cam.size[1]:<4} {cam.fx:>7g} {cam.fy:>7g} {cam.height:>8g} "
                  f"{cam.tilt:>5g} {hf:>6.1f} {vf:>6.1f}")


@camera_app.command("show")
def camera_show(spec: str = typer.Argument(..., help=CAMERA_HELP),
                as_json: bool = typer.Option(False, "--json", help="Print one JSON object instead of YAML.")):
    """Show a camera (preset or file) as YAML, or JSON with --json.

    \b
    Example:
      vcprep camera show camvid
      vcprep camera show examples/kitti/calib/um_000000.txt --json
    """
    cam = load_camera(spec)
    hf, vf = cam.fov_deg()
    if as_json:
        emit_json({**cam.to_dict(), "fov_deg": [round(hf, 3), round(vf, 3)]})
    else:
        print(camera_to_yaml(cam) + f"# field of view: {hf:.1f} x {vf:.1f} degrees")


@camera_app.command("design")
def camera_design(cameras: List[str] = typer.Argument(..., help="physical cameras: " + CAMERA_HELP),
                  out: Path = typer.Option(..., "-o", "--out", help="virtual camera YAML to write"),
                  pan_range: float = typer.Option(20.0, help="expected pan variation, +/- degrees"),
                  tilt_range: float = typer.Option(15.0, help="expected tilt variation, +/- degrees"),
                  rule: str = typer.Option("shift", help="'shift' (paper-like: a pose change shifts the image by "
                                                         "f*tan(angle)) or 'exact' (worst case of exact homographies)"),
                  name: str = typer.Option("virtual", help="name of the designed camera"),
                  above: Optional[float] = typer.Option(None, "--above",
                                                        help="crop to the road: keep only this many degrees above "
                                                             "the horizon (plus the tilt range); default: the "
                                                             "paper's rectangle centred on the horizon")):
    """Derive a virtual camera from physical cameras (paper §4.1.2): mean height, max focal,
    central principal point, FOV that holds the lower half of every camera under the pose ranges.
    --above crops the rows above the horizon that can never be road (an exact crop: only cy and
    the height change).

    \b
    Example:
      vcprep camera design camvid cityscapes kitti qian toronto2020 -o virtual.yaml
      vcprep camera design camvid kitti --pan-range 10 --tilt-range 5 --above 8 -o road.yaml
    """
    from .virtual_camera import design_virtual_camera

    cams = [load_camera(c) for c in cameras]
    design = design_virtual_camera(cams, pan_range=pan_range, tilt_range=tilt_range, rule=rule, name=name,
                                   above=above)
    from .imageio import write_bytes_atomic

    text = camera_to_yaml(design.camera) + design.report()
    write_bytes_atomic(ensure_parent(out), text.encode())
    err(design.report().replace("# ", "").rstrip())
    print(out)


@camera_app.command("ego")
def camera_ego(labels: Path = typer.Option(..., "--labels", "-l", help="folder of one camera's label images "
                                           "(subfolders included; >= 5 frames)"),
               label_format: str = typer.Option(..., "--label-format", "-f",
                                                help=f"{', '.join(LABEL_FORMATS)} or values:road=3;ignore=11"),
               camera: Optional[str] = typer.Option(None, "--camera", "-c", help="the camera to write with the rows "
                                                    "found (preset or file; with -o)"),
               out: Optional[Path] = typer.Option(None, "-o", "--out", help="camera YAML to write: --camera with "
                                                  "ego_rows set to the rows found"),
               as_json: bool = typer.Option(False, "--json", help="Print one JSON object instead of the row count."),
               quiet: bool = typer.Option(False, "--quiet", "-q", help="no summary on stderr")):
    """Find the bottom rows that show your own vehicle (bonnet) from the labels: the ignore region
    common to >= 90 % of the frames that grows up from the bottom edge. Prints the row count (0: no
    own vehicle); with --camera and -o writes that camera with ego_rows set.

    \b
    Example:
      vcprep camera ego --labels data/camvid/trainannot --label-format camvid
      vcprep camera ego -l cs/labels -f 'values:road=1;ignore=255;max=255' -c cs/camera.yaml -o cs/camera-ego.yaml
    """
    from dataclasses import replace

    from .build import find_images
    from .ego import ego_rows_from_label_files, rows_at_height
    from .imageio import write_bytes_atomic

    if out is not None and camera is None:
        raise InputError("-o writes a camera, but no --camera was given", out, "add --camera CAM (preset or file)")
    fmt = get_label_format(label_format)
    files = find_images(labels, "label")
    est = ego_rows_from_label_files(files, fmt, labels)
    cam = load_camera(camera) if camera is not None else None
    rows = rows_at_height(est, cam.size[1]) if cam is not None else est.rows
    if not quiet:
        err(f"{labels}: {est.describe()}" + (f"; at the camera's {cam.size[1]} rows: ego_rows {rows}"
                                              if cam is not None and cam.size[1] != est.size[1] else ""))
    if out is not None:
        write_bytes_atomic(ensure_parent(out), camera_to_yaml(replace(cam, ego_rows=rows)).encode())
    if as_json:
        emit_json({**est.to_dict(), "ego_rows_at_camera_size": rows, **({"out": str(out)} if out else {})})
    else:
        print(out if out is not None else rows)


@camera_app.command("estimate")
def camera_estimate_cmd(
        images: List[Path] = typer.Argument(..., help="frames of ONE camera: files or folders (subfolders included)"),
        out: Path = typer.Option(..., "-o", "--out", help="camera YAML to write (each value with how it was found)"),
        labels: Optional[Path] = typer.Option(None, "--labels", "-l", help="label folder: finds the own vehicle "
                                              "(ego_rows) from the ignore region common to the frames"),
        label_format: Optional[str] = typer.Option(None, "--label-format", "-f",
                                                   help=f"{', '.join(LABEL_FORMATS)} or values:road=3;ignore=11"),
        fx: Optional[float] = typer.Option(None, "--fx", min=1.0, help="focal length in pixels, if you know it"),
        hfov: Optional[float] = typer.Option(None, "--hfov", min=1.0, max=179.0,
                                             help="horizontal field of view in degrees, if you know it"),
        height: Optional[float] = typer.Option(None, "--height", min=0.05, help="mounting height in metres"),
        source_size: Optional[str] = typer.Option(None, "--source-size", help="WxH the frames were resized from "
                                                  "(non-square pixels), e.g. 2048x1024"),
        name: str = typer.Option("estimated", "--name", help="name of the camera"),
        vps: Optional[Path] = typer.Option(None, "--vps", help="also write each frame's road VP (the CSV "
                                           "'vcprep warp --within FILE' reads): per-frame poses where the mount varies"),
        as_json: bool = typer.Option(False, "--json", help="print one JSON report (values, how, how sure) instead "
                                     "of the path"),
        quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar or summary on stderr")):
    """Estimate a camera nobody calibrated from its own frames: the horizon, tilt and pan from the
    frames' road vanishing points, the own vehicle from labels. The focal length and the height
    are not fixed by road frames: they come from --fx/--hfov, --height or the files' EXIF, else
    they are ASSUMED (60 deg FOV, 1.4 m) and said so. Every value in the YAML carries how it was
    found and how sure it is.

    \b
    Example:
      vcprep camera estimate data/dashcam -o dashcam.yaml
      vcprep camera estimate cs/images --source-size 2048x1024 --labels cs/labels -f 'values:road=1;ignore=255' -o cs.yaml
    """
    from tqdm import tqdm

    from .camera_estimate import estimate_camera, estimate_to_yaml
    from .cliutil import parse_size
    from .imageio import write_bytes_atomic
    from .vanishing_point import write_vp_csv

    if fx is not None and hfov is not None:
        raise InputError("--fx and --hfov both given", None, "give one of them")
    if labels is not None and label_format is None:
        raise InputError("--labels given without --label-format", labels, f"add --label-format ({', '.join(LABEL_FORMATS)})")
    files = _image_files(images)
    label_files = None
    if labels is not None:
        from .build import find_images

        label_files = find_images(labels, "label")
    bar = tqdm(total=len(files), desc="estimate", unit="img", disable=True if quiet else None, leave=False)
    try:
        est = estimate_camera(files, name=name, fx=fx, hfov=hfov, height=height,
                              source_size=parse_size(source_size, "--source-size") if source_size else None,
                              labels=label_files, label_format=get_label_format(label_format) if labels else None,
                              on_image=lambda i: bar.update())
    finally:
        bar.close()
    write_bytes_atomic(ensure_parent(out), estimate_to_yaml(est).encode())
    if vps is not None:
        write_vp_csv(ensure_parent(vps), est.ids, est.vps)
    if as_json:
        emit_json({**est.to_dict(), "out": str(out), **({"vps": str(vps)} if vps else {})})
    else:
        print(out)
    if not quiet:
        v = est.values
        err(f"{out}: tilt {v['tilt'].value:g} +/- {v['tilt'].sure:g} deg, pan {v['pan'].value:g} deg, horizon row "
            f"{v['horizon_row'].value:g} ({est.accepted} of {count(est.frames, 'frame')} with a road VP); "
            f"ego_rows {est.camera.ego_rows}")
        for w in est.warnings:
            err(f"assumed {w}")


@app.command("warp")
def warp_cmd(
    camera: str = typer.Option(..., "--camera", "-c", help=FRAMES_HELP + ", or 'estimate': estimated from these "
                               "frames (as 'vcprep camera estimate' does; written to STORE/camera.estimated.yaml)"),
    images: Path = typer.Option(..., "--images", "-i", help="folder of source images (subfolders included)"),
    out: Path = typer.Option(..., "--out", "-o", help="store directory (created, or updated in place)"),
    labels: Optional[Path] = typer.Option(None, "--labels", "-l", help="folder of label images, a tree mirroring "
                                          "--images (e.g. gtFine/train for leftImg8bit/train)"),
    label_format: Optional[str] = typer.Option(None, "--label-format", "-f",
                                               help=f"{', '.join(LABEL_FORMATS)} or values:road=3;ignore=11"),
    virtual: str = typer.Option("virtual", "--virtual", help="virtual camera: preset or YAML file"),
    scale: float = typer.Option(0.125, "--scale", "-s", help="store scale of the full virtual camera (1/8 -> 688x350)"),
    id_prefix: str = typer.Option("", "--id-prefix", help="prefix for item ids (keeps datasets apart in one store)"),
    complete: str = typer.Option("projective", "--complete", help=COMPLETE_HELP),
    within: str = typer.Option("none", "--within", help=WITHIN_HELP),
    vp_smooth: int = typer.Option(0, "--vp-smooth", min=0, help=SMOOTH_HELP),
    jobs: Optional[int] = typer.Option(None, "--jobs", "-j", min=1, help=JOBS_HELP),
    shard: Optional[str] = typer.Option(None, "--shard", help=SHARD_HELP),
    keep_going: bool = typer.Option(False, "--keep-going", "-k", help=KEEP_GOING_HELP),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar or summary on stderr"),
):
    """Warp a folder of images (and labels) from CAMERA into the virtual camera store OUT.

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
      vcprep warp --camera camvid --images data/camvid/val --out stores/val --within estimate
      vcprep warp --camera camvid --images data/camvid/val --out stores/val --within vps.csv
      vcprep warp --camera kitti/training/calib --images kitti/training/image_2 \\
          --labels kitti/training/gt_image_2 --label-format kitti --out stores/kitti   # per-frame calibration
      vcprep warp --camera cityscapes/camera/train --images cityscapes/leftImg8bit/train \\
          --labels cityscapes/gtFine/train --label-format cityscapes --out stores/cs   # nested city folders
    """
    from .build import WarpSettings, list_dataset, warp_dataset
    from .store import Shard

    part = Shard.parse(shard) if shard else None
    if labels is not None and label_format is None:
        raise InputError("--labels given without --label-format", labels, f"add --label-format ({', '.join(LABEL_FORMATS)})")
    fmt = get_label_format(label_format) if label_format else None
    check_data_folders(images, labels)
    items = list_dataset(images, labels, fmt, id_prefix)
    estimate = None
    if camera == "estimate":  # the camera from these frames (and the own vehicle from their labels)
        from .camera_estimate import estimate_camera, estimate_to_yaml

        if not quiet:
            err(f"estimating the camera from {count(len(items), 'frame')}")
        est_labels = [j.label for j in items if j.label is not None]
        estimate = estimate_camera([j.image for j in items], name="estimated", ids=[j.id for j in items],
                                   labels=est_labels if len(est_labels) >= 5 else None, label_format=fmt)
        cam = estimate.camera
    else:
        cam = camera_for(camera, items[0].image)
    if not isinstance(cam, Camera) and within != "none":
        raise InputError("--within needs one camera; a per-frame calibration folder already gives every frame its "
                         "exact pose", camera, "drop --within, or give one camera file or preset")
    virt = load_camera(virtual)
    # VPs over all frames even for one shard: the fallback VP and smoothing depend on the whole run
    poses = _within_poses(items, cam, within, vp_smooth, id_prefix, quiet)
    settings = WarpSettings(camera=cam, virtual=virt, scale=scale, label_format=fmt, completion=complete, poses=poses,
                            workers=jobs or default_jobs(), shard=part, keep_going=keep_going, progress=not quiet)
    store, summary = warp_dataset(items, out, settings)
    if estimate is not None:
        from .imageio import write_bytes_atomic

        write_bytes_atomic(out / "camera.estimated.yaml", estimate_to_yaml(estimate).encode())
        if not quiet:
            v = estimate.values
            err(f"camera ESTIMATED from the frames ({out / 'camera.estimated.yaml'}): tilt {v['tilt'].value:g} deg, "
                f"pan {v['pan'].value:g} deg; " + "; ".join(f"assumed {w}" for w in estimate.warnings))
    _finish(out, summary, quiet, f" (store {store.store_size[0]}x{store.store_size[1]}"
                                 f"{f', shard {part}' if part else ''})")


def _vp_counts(results) -> str:
    from collections import Counter

    c = Counter(r.status for r in results)
    return ", ".join(f"{c[k]} {k}" for k in ("accepted", "fallback", "given") if c[k])


def _within_poses(jobs, cam: Camera, within: str, smooth: int, id_prefix: str, quiet: bool):
    """The ``poses`` mapping of :class:`vcprep.build.WarpSettings` from ``--within`` (None for 'none')."""
    if within == "none":
        if smooth:
            raise InputError("--vp-smooth needs --within estimate", None, "add --within estimate or drop --vp-smooth")
        return None
    from tqdm import tqdm

    from .build import ItemPose
    from .vanishing_point import vps_for_items

    if within != "estimate" and smooth:
        raise InputError("--vp-smooth applies to estimated VPs only", within, "use --within estimate")
    bar = tqdm(total=len(jobs), desc="vp", unit="img", disable=True if quiet or within != "estimate" else None, leave=False)
    try:
        results = vps_for_items([j.image for j in jobs], [j.id for j in jobs], cam, within, smooth,
                                id_prefix=id_prefix, on_image=lambda i: bar.update())
    finally:
        bar.close()
    if not quiet:
        err(f"vanishing points: {_vp_counts(results)}")
    return {j.id: ItemPose((r.vp[0], r.vp[1]), r.status) for j, r in zip(jobs, results)}


def _finish(out: Path, summary, quiet: bool, extra: str = "", verb: str = "built") -> None:
    """End of a store build: failures (always), summary and notes (unless quiet), the path on
    stdout; exit 1 via StoreError if items failed (--keep-going)."""
    from .errors import StoreError

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
    from .build import complete_store
    from .store import Shard

    part = Shard.parse(shard) if shard else None
    st, summary = complete_store(store, method, progress=not quiet, workers=jobs or default_jobs(), shard=part,
                                 keep_going=keep_going)
    _finish(store, summary, quiet, f" ({method}{f', shard {part}' if part else ''})", verb="completed")


@store_app.command("show")
def store_show(store: Path = typer.Argument(..., help="store directory"),
               as_json: bool = typer.Option(False, "--json", help="one JSON item record per line")):
    """List the items of a store (id, camera, source), or their full records with --json.

    \b
    Example:
      vcprep store show stores/camvid --json | head -1
    """
    from .store import Store

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
                 jobs: Optional[int] = typer.Option(None, "--jobs", "-j", min=1, help=JOBS_HELP),
                 quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar or summary on stderr")):
    """Check a store: every recorded PNG exists, decodes, has the store size, allowed values
    and its recorded SHA-256; sources still hash as recorded; no orphan (unrecorded) PNGs or
    temp files. Prints one line per problem (id, kind, file, detail; --json: objects) and
    exits 1 if there is any. A build skips items whose files exist, so to redo items with bad
    files run --repair first, then the build.

    \b
    Example:
      vcprep store verify stores/camvid
      vcprep store verify stores/camvid --no-sources --json | jq -r .id | sort -u
      vcprep store verify stores/camvid --repair; vcprep warp ... --out stores/camvid
    """
    from .build import say_on_stderr
    from .errors import StoreError
    from .store_check import verify_and_repair, verify_store

    if repair:  # under the store lock: waits for a running build, whose files in flight are no orphans
        report, dropped, removed = verify_and_repair(store, sources, jobs or default_jobs(), not quiet,
                                                     on_wait=None if quiet else say_on_stderr)
    else:
        report = verify_store(store, check_sources=sources, workers=jobs or default_jobs(), progress=not quiet)
    for p in report.problems:
        if as_json:
            from dataclasses import asdict

            emit_json(asdict(p))
        else:
            print(p.line())
    if not quiet:
        err(f"{store}: {report.summary()}")
    if report.problems:
        bad = report.bad_items
        named = ", ".join(bad[:10]) + (f" and {len(bad) - 10} more" if len(bad) > 10 else "")
        if repair:
            fix = (f"repaired: dropped {count(len(dropped), 'item')}, deleted {count(removed, 'file')}; re-run the build command to "
                   "redo them")
        else:
            fix = "run 'vcprep store verify --repair STORE', then the build command again, to redo them"
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
    from .store_check import store_info

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
    manifest.jsonl and remove temp files of interrupted writes. Run it once every shard has
    finished (it waits for running builds: it holds the store lock). The store is readable
    before (parts are read too); merging makes it one file.

    \b
    Example:
      vcprep warp -c camvid -i data/camvid/train -o stores/camvid --shard 1/2 &
      vcprep warp -c camvid -i data/camvid/train -o stores/camvid --shard 2/2; wait
      vcprep store merge stores/camvid
    """
    from .build import say_on_stderr
    from .store_check import merge_store

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
    from .backproject import backproject_folder

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
    from .prior import compute_prior, open_stores, prior_meta, write_prior

    opened = open_stores(stores)
    prior, n_unlabelled = compute_prior(opened)
    meta = prior_meta(opened, n_unlabelled)
    write_prior(ensure_parent(out), prior, meta)
    if not quiet:
        w, h = opened[0].store_size
        err(f"{out}: p_g over {count(meta['items'], 'labelled item')} of {count(len(opened), 'store')} ({w}x{h}); "
            f"{count(n_unlabelled, 'pixel')} with no labelled item (set to 0)")
    print(out)


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
    from .figures import prior_figure
    from .prior import check_thresholds, mean_image, open_stores, prior_counts, prior_from_counts

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
    from .figures import warp_figure
    from .store import Store

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
    from .figures import completion_figure
    from .store import Store

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
    from .figures import footprints_figure

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
    from .figures import fov_figure

    save_figure(out, fov_figure([load_camera(c) for c in cameras], load_camera(virtual)))


def _image_files(paths: List[Path]) -> list[Path]:
    """IMAGES arguments: files as given, folders expanded to their images (recursively, sorted)."""
    from .build import find_images
    from .imageio import IMAGE_EXTENSIONS

    files: list[Path] = []
    for p in paths:
        if p.is_dir():
            inside = find_images(p)
            if not inside:
                raise InputError("no images in folder", p, f"give image files ({', '.join(IMAGE_EXTENSIONS)})")
            files += inside
        elif not p.exists():
            raise InputError("image file not found", p, "check the path")
        else:
            files.append(p)
    return files


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
    import sys

    from tqdm import tqdm

    from .vanishing_point import estimate_files, format_vp_csv, write_vp_csv

    files = _image_files(images)
    ids = [f.stem for f in files]
    seen: dict[str, Path] = {}
    for f, i in zip(files, ids):
        if i in seen:
            raise InputError(f"duplicate image id '{i}' (also {seen[i]})", f, "VP files are keyed by file stem: give each image a unique name")
        seen[i] = f
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
        err(f"{count(len(results), 'image')}: {_vp_counts(results)}")


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
    from .figures import camera_figure
    from .vanishing_point import read_vp_csv

    files = _image_files(images)
    n = min(samples, len(files))
    pick = [files[round(i * (len(files) - 1) / max(1, n - 1))] for i in range(n)]
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
    from .figures import vp_figure
    from .imageio import read_image
    from .vanishing_point import VPConfig, apply_reliability, estimate_vp, prior_window

    img = read_image(image).array
    cam = camera_for(camera, image, per_frame=False).for_image_size((img.shape[1], img.shape[0]), image)
    cfg = VPConfig()
    res = apply_reliability([estimate_vp(img, cam, cfg)], [cam])[0]
    save_figure(out, vp_figure(img, res, cam, prior_window(cam, cfg.pan_range, cfg.tilt_range)))


@app.command("simulate")
def simulate_cmd(
    camera: str = typer.Option(..., "--camera", "-c", help=CAMERA_HELP),
    images: Path = typer.Option(..., "--images", "-i", help="folder of source images"),
    out: Path = typer.Option(..., "--out", "-o", help="output dataset folder (new, empty, or an earlier simulate output)"),
    labels: Optional[Path] = typer.Option(None, "--labels", "-l", help="folder of label images (warped by nearest "
                                          "neighbour, raw values and file names kept)"),
    label_format: Optional[str] = typer.Option(None, "--label-format", "-f",
                                               help=f"{', '.join(LABEL_FORMATS)} or values:road=3;ignore=11"),
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
    from .build import list_dataset
    from .cliutil import parse_size
    from .simulate import SimulateParams, simulate_dataset

    if labels is not None and label_format is None:
        raise InputError("--labels given without --label-format", labels, f"add --label-format ({', '.join(LABEL_FORMATS)})")
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


def main() -> None:
    run_app(app, "vcprep")


if __name__ == "__main__":
    main()
