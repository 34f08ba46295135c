"""``vcprep``: the command line. Parses, calls the library, prints; nothing else lives here."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from . import __version__
from .camera import PRESETS, Camera, camera_to_yaml, load_camera
from .cliutil import emit_json, err, run_app
from .errors import InputError
from .imageio import image_size_from_header
from .labels import LABEL_FORMATS, get_label_format

app = typer.Typer(rich_markup_mode=None, pretty_exceptions_enable=False, add_completion=False, no_args_is_help=True,
                  help="Reproject road images from any camera into one standard virtual camera (VCSeg).\n\n"
                       "Add --debug to any command to see a traceback on error.")
camera_app = typer.Typer(rich_markup_mode=None, no_args_is_help=True, help="Camera models: show and design.")
store_app = typer.Typer(rich_markup_mode=None, no_args_is_help=True, help="Inspect virtual-camera image stores.")
figure_app = typer.Typer(rich_markup_mode=None, no_args_is_help=True, help="Figures (PNG) a person can look at.")
app.add_typer(camera_app, name="camera")
app.add_typer(store_app, name="store")
app.add_typer(figure_app, name="figure")

CAMERA_HELP = f"camera preset ({', '.join(PRESETS)}) or file (.yaml camera, .txt KITTI calib, .json Cityscapes)"


def _version(value: bool):
    if value:
        print(f"vcprep {__version__}")
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", callback=_version, is_eager=True, help="Print the version.")):
    pass


def camera_for(spec: str, sample_image: Path | None = None) -> Camera:
    """Load ``spec``; calibration files (.txt/.json) carry no image size, so take it from a frame."""
    size = None
    if sample_image is not None and not str(spec) in PRESETS and Path(spec).suffix.lower() in (".txt", ".json"):
        try:
            size = image_size_from_header(sample_image.read_bytes()[:65536])
        except OSError:
            size = None
    return load_camera(spec, image_size=size)


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
                  name: str = typer.Option("virtual", help="name of the designed camera")):
    """Derive a virtual camera from physical cameras (paper §4.1.2): mean height, max focal,
    central principal point, FOV that holds the lower half of every camera under the pose ranges.

    \b
    Example:
      vcprep camera design camvid cityscapes kitti qian toronto2020 -o virtual.yaml
    """
    from .virtual_camera import design_virtual_camera

    cams = [load_camera(c) for c in cameras]
    design = design_virtual_camera(cams, pan_range=pan_range, tilt_range=tilt_range, rule=rule, name=name)
    from .imageio import write_bytes_atomic

    text = camera_to_yaml(design.camera) + design.report()
    try:
        write_bytes_atomic(out, text.encode())
    except (FileNotFoundError, NotADirectoryError):
        raise InputError("cannot write here (parent folder missing)", out, "create the folder first") from None
    err(design.report().replace("# ", "").rstrip())
    print(out)


@app.command("warp")
def warp_cmd(
    camera: str = typer.Option(..., "--camera", "-c", help=CAMERA_HELP),
    images: Path = typer.Option(..., "--images", "-i", help="folder of source images"),
    out: Path = typer.Option(..., "--out", "-o", help="store directory (created, or updated in place)"),
    labels: Optional[Path] = typer.Option(None, "--labels", "-l", help="folder of label images"),
    label_format: Optional[str] = typer.Option(None, "--label-format", "-f",
                                               help=f"{', '.join(LABEL_FORMATS)} or values:road=3;ignore=11"),
    virtual: str = typer.Option("virtual", "--virtual", help="virtual camera: preset or YAML file"),
    scale: float = typer.Option(0.125, "--scale", "-s", help="store scale of the full virtual camera (1/8 -> 688x350)"),
    id_prefix: str = typer.Option("", "--id-prefix", help="prefix for item ids (keeps datasets apart in one store)"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar or summary on stderr"),
):
    """Warp a folder of images (and labels) from CAMERA into the virtual camera store OUT.

    Images are resampled bilinearly, labels by nearest neighbour and stored as 0 = not road,
    1 = road, 255 = ignore. Re-running with unchanged inputs does no work; a changed image,
    label, camera or parameter redoes exactly the affected items. Prints the store path.

    \b
    Example:
      vcprep warp --camera camvid --images data/camvid/train \\
          --labels data/camvid/trainannot --label-format camvid --out stores/camvid
    """
    from .build import list_dataset, warp_dataset

    if labels is not None and label_format is None:
        raise InputError("--labels given without --label-format", labels, f"add --label-format ({', '.join(LABEL_FORMATS)})")
    fmt = get_label_format(label_format) if label_format else None
    jobs = list_dataset(images, labels, fmt, id_prefix)
    cam = camera_for(camera, jobs[0].image)
    virt = load_camera(virtual)
    store, summary = warp_dataset(jobs, cam, virt, scale, out, fmt, progress=not quiet)
    if not quiet:
        err(f"{out}: {summary.line()} (store {store.store_size[0]}x{store.store_size[1]})")
    print(out)


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
        err(f"{store}: {len(st)} items, {st.store_size[0]}x{st.store_size[1]} at scale {st.scale:g}")


@app.command("backproject")
def backproject_cmd(store: Path = typer.Argument(..., help="store the masks belong to"),
                    masks: Path = typer.Argument(..., help="folder of virtual-domain PNGs named <id>.png"),
                    out: Path = typer.Option(..., "--out", "-o", help="output folder (created)"),
                    kind: str = typer.Option("mask", help="'mask' (nearest) or 'prob' (bilinear)"),
                    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar")):
    """Map virtual-domain masks or probability maps back to each item's original camera,
    exactly inverting its H. Writes OUT/<id>.png at the source image size; source pixels
    outside the virtual image get 0.

    \b
    Example:
      vcprep backproject stores/camvid preds/virtual --out preds/camvid --kind prob
    """
    from .backproject import backproject_folder

    n = backproject_folder(store, masks, out, kind=kind, progress=not quiet)
    if not quiet:
        err(f"{out}: {n} maps back-projected")
    print(out)


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

    import cv2

    st = Store.open(store)
    fig = warp_figure(st, ids or None, width=width)
    from .imageio import write_png

    try:
        write_png(out, fig, compression=3)
    except (FileNotFoundError, NotADirectoryError):
        raise InputError("cannot write here (parent folder missing)", out, "create the folder first") from None
    print(out)


def main() -> None:
    run_app(app, "vcprep")


if __name__ == "__main__":
    main()
