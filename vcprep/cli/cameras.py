"""Commands on cameras: ``cameras``, ``camera show|design|ego|estimate``."""
from __future__ import annotations

import tempfile
from dataclasses import replace
from pathlib import Path
from typing import List, Optional

import typer
from tqdm import tqdm

from ..camera.pinhole import PRESETS
from ..camera.files import camera_to_yaml
from ..camera.sources import load_camera
from ..camera.estimate import estimate_camera, estimate_to_yaml
from ..cliutil import count, emit_json, ensure_parent, err, parse_size
from ..dataset import find_images
from ..camera.ego import ego_rows_from_frame_files, ego_rows_from_label_files, rows_at_height
from ..errors import InputError
from ..io.images import write_bytes_atomic
from ..io.video import frames_of, is_video
from ..labels import get_label_format
from ..vp.reliability import write_vp_csv
from ..camera.virtual import design_virtual_camera
from .common import CAMERA_HELP, LABEL_FORMAT_HELP, app, camera_app, check_label_format, image_files


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
                                                             "paper's rectangle centred on the horizon"),
                  extent: str = typer.Option("max", help="'max': the rectangle holds every camera; 'median': it "
                                                         "reaches sideways and down as far as the median camera "
                                                         "(the widest and lowest cameras are cut)")):
    """Derive a virtual camera from physical cameras (paper §4.1.2): mean height, max focal,
    central principal point, FOV that holds the lower half of every camera under the pose ranges.
    --above crops the rows above the horizon that can never be road (an exact crop: only cy and
    the height change). --extent median sizes the rectangle by the median camera, so that one very
    wide or very low camera does not shrink every other camera's images at a fixed pixel budget.

    \b
    Example:
      vcprep camera design camvid cityscapes kitti qian toronto2020 -o virtual.yaml
      vcprep camera design camvid kitti --pan-range 10 --tilt-range 5 --above 8 -o road.yaml
      vcprep camera design camvid cityscapes lums.yaml idd.yaml --above 8 --extent median -o road.yaml
    """
    cams = [load_camera(c) for c in cameras]
    design = design_virtual_camera(cams, pan_range=pan_range, tilt_range=tilt_range, rule=rule, name=name,
                                   above=above, extent=extent)

    text = camera_to_yaml(design.camera) + design.report()
    write_bytes_atomic(ensure_parent(out), text.encode())
    err(design.report().replace("# ", "").rstrip())
    print(out)


@camera_app.command("ego")
def camera_ego(labels: Optional[Path] = typer.Option(None, "--labels", "-l", help="folder of one camera's label "
                                                     "images (subfolders included; >= 5 frames)"),
               label_format: Optional[str] = typer.Option(None, "--label-format", "-f",
                                                          help=LABEL_FORMAT_HELP),
               images: Optional[Path] = typer.Option(None, "--images", "-i", help="without labels: folder of one "
                                                     "camera's frames (>= 20 distinct, a few dozen over the drive)"),
               camera: Optional[str] = typer.Option(None, "--camera", "-c", help="the camera to write with the rows "
                                                    "found (preset or file; with -o)"),
               out: Optional[Path] = typer.Option(None, "-o", "--out", help="camera YAML to write: --camera with "
                                                  "ego_rows set to the rows found"),
               as_json: bool = typer.Option(False, "--json", help="Print one JSON object instead of the row count."),
               quiet: bool = typer.Option(False, "--quiet", "-q", help="no summary on stderr")):
    """Find the bottom rows that show your own vehicle (bonnet) from the labels: the ignore region
    common to >= 90 % of the frames that grows up from the bottom edge; without labels, from the
    frames (--images): the near-horizontal edge that stays put while the scene moves. Prints the row
    count (0: no own vehicle); with --camera and -o writes that camera with ego_rows set.

    \b
    Example:
      vcprep camera ego --labels data/camvid/trainannot --label-format camvid
      vcprep camera ego --images data/camvid/train
      vcprep camera ego -l cs/labels -f 'values:road=1;ignore=255;max=255' -c cs/camera.yaml -o cs/camera-ego.yaml
    """
    if out is not None and camera is None:
        raise InputError("-o writes a camera, but no --camera was given", out, "add --camera CAM (preset or file)")
    if labels is not None:
        if label_format is None:
            raise InputError("labels given without a label format", labels, "add --label-format (e.g. camvid)")
        source = labels
        est = ego_rows_from_label_files(find_images(labels, "label"), get_label_format(label_format), labels)
    elif images is not None:
        source = images
        if not quiet:
            err(f"{images}: no labels: finding the own vehicle from the frames (an edge that stays put while the "
                "scene moves)")
        est = ego_rows_from_frame_files(find_images(images), images)
    else:
        raise InputError("no --labels and no --images", None, "give --labels DIR --label-format FMT, or --images DIR")
    cam = load_camera(camera) if camera is not None else None
    rows = rows_at_height(est, cam.size[1]) if cam is not None else est.rows
    if not quiet:
        err(f"{source}: {est.describe()}" + (f"; at the camera's {cam.size[1]} rows: ego_rows {rows}"
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
                                                   help=LABEL_FORMAT_HELP),
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
      vcprep camera estimate drive.mp4 -o dashcam.yaml     # a video: 48 frames spread over it
      vcprep camera estimate cs/images --source-size 2048x1024 --labels cs/labels -f 'values:road=1;ignore=255' -o cs.yaml
    """
    if fx is not None and hfov is not None:
        raise InputError("--fx and --hfov both given", None, "give one of them")
    check_label_format(labels, label_format)
    videos = [p for p in images if is_video(p)]
    if videos and labels is not None:
        raise InputError("--labels is for image frames, not videos", videos[0], "drop --labels, or give the frames")
    label_files = find_images(labels, "label") if labels is not None else None
    with tempfile.TemporaryDirectory(prefix="vcprep-frames-") as tmp:  # a video: a sample of its frames
        files = image_files([p for p in images if not is_video(p)]) if len(videos) < len(images) else []
        files += frames_of(videos, tmp)
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
