"""``vctrain predict`` (a model, the geometric prior or an exported graph on images, videos or a
store: :func:`vctrain.predict.inputs.predict_inputs`) and ``vctrain export`` (the ONNX graph with
the camera inside: :func:`vctrain.deploy.export.export_onnx`)."""
from __future__ import annotations

from pathlib import Path
from typing import List, Optional, Tuple

import typer

from vcprep.cliutil import corridor_option, ensure_parent, err, range_option, res_option

from ..predict.settings import BEYOND, DEFAULT_BEYOND, DEFAULT_ENGINE, GRAPH_ENGINE, STUDY_IOU_TOLERANCE
from ..shipped import SHIPPED
from .common import app, model_arg, path_or_json, pin_threads, threads_option


EGO_HELP = ("the own vehicle (bonnet, dashboard) in a video or a folder of one camera's frames, predicted "
            "'not road': auto (the camera's ego_rows, else found from up to 48 frames spread over them, said on "
            "stderr; a model that reads frames as they are: per source in a folder of several, by folder, "
            "BDD100K- or CamVid-style name prefix), none (no search: the camera as given) or N bottom rows; default: auto for a virtual-camera "
            "model, none for a model that reads frames as they are (the shipped model: give --ego auto or N "
            "for a dashcam)")
ENGINE_HELP = ("what runs the network. A .pt model: auto (OpenVINO, else onnxruntime, where installed and on the "
               "CPU: the same network exported in memory, about 2x faster than PyTorch on a CPU; else torch, said "
               "once on stderr), torch (PyTorch: a study's masks bit for bit; a GPU's), onnx / openvino (one of the "
               "two runtimes). Their P(road) is PyTorch's within 3e-6, so a pixel at P = 0.5 can differ: a study's "
               f"road IoU within {STUDY_IOU_TOLERANCE} of auto's; default {DEFAULT_ENGINE}. A graph (.onnx): "
               f"openvino, onnx or auto; default {GRAPH_ENGINE}. Said on stderr (the start-up line: load and "
               "export/compile seconds, apart from the frames') and recorded in OUT/predict.json")
BEYOND_RULES = {"hybrid": "the network on the grown rectangle, P(road) where the ray from the road VP leaves the "
                          "training rectangle beyond it",
                "extend": "the network's own values there",
                "rays": "the network on the training rectangle alone, rays beyond it"}
BEYOND_HELP = ("a virtual-camera model, frame pixels outside its training rectangle (a camera lower, steeper or "
               "wider than the training one): " + ", ".join(f"{r} ({BEYOND_RULES[r]})" for r in BEYOND)
               + f"; default {DEFAULT_BEYOND}")
BEV_HELP = ("also the road in a bird's-eye view and in metres (needs --camera): OUT/<stem>_bev_prob.png (0-255, "
            "unseen 0) and <stem>_bev_mask.png (the values of 'vcprep bev': 0 not road, 1 road, 255 unseen), far row "
            "first; stdout: one JSON line per frame (id, free_m, width_m, area_m2, pose) instead of the paths; an "
            "inset in the overlays. Each frame's pose from its road VP (--within none: the camera's nominal pose)")
CAMERA_HELP = ("camera of the images: preset or file (.yaml, KITTI .txt, Cityscapes .json), or a folder of per-frame "
               "calibration files matched by stem, or 'estimate' (from these images, as 'vcprep camera estimate' "
               "does); a .yaml camera's ego_rows (its own vehicle) are never warped; the prediction there continues "
               "the scene above them")
OVERLAY_HELP = ("also write OUT/<stem>_overlay.png (road in green); for a video OUT/<stem>_overlay.mp4 (road in green; "
                "the horizon and the road VP of each frame too, only with --camera)")
WITHIN_HELP = ("per-image VP correction: auto (as the model was trained), estimate, a CSV id,u,v, or none; with --bev "
               "also the BEV's poses (auto: each frame's own road VP)")

# predict's arguments and options, declared once each (the command's signature names them)
MODEL_ARG = typer.Argument(None, help="model written by 'vctrain fit', or a shipped model's name from any folder: "
                                      f"shipped (= {SHIPPED}), or another under models/ (left out with --prior)")
IMAGES_ARG = typer.Argument(None, help="image files or folders, or video files (.mp4 .avi .mkv .mov ...)")
OUT_OPT = typer.Option(..., "--out", "-o", help="output folder (created)")
CAMERA_OPT = typer.Option(None, "--camera", "-c", help=CAMERA_HELP)
PRIOR_OPT = typer.Option(None, "--prior", help="no model: segment with the geometric prior written by 'vcprep prior' "
                                               "(p_g >= 0.5, back-projected)")
STORE_OPT = typer.Option(None, "--store", help="predict every item of this store instead of IMAGES")
DEVICE_OPT = typer.Option("auto", "--device", help="auto, cpu, cuda, cuda:N")
ENGINE_OPT = typer.Option(None, "--engine", help=ENGINE_HELP)
KEEP_STORE_OPT = typer.Option(None, "--keep-store", help="keep the warped images in this store")
WITHIN_OPT = typer.Option("auto", "--within", help=WITHIN_HELP)
OVERLAY_OPT = typer.Option(False, "--overlay", help=OVERLAY_HELP)
MASK_VIDEO_OPT = typer.Option(False, "--mask-video", help="a video's masks as one lossless video OUT/<stem>_mask.mkv "
                                                          "instead of a PNG per frame")
VP_RANGE_OPT = typer.Option(None, "--vp-range", help="estimated VPs: searched and accepted within PAN TILT degrees of "
                                                     "the camera's pose (default: the rule the model was trained "
                                                     "with, e.g. a study's pan_range tilt_range; said on stderr)")
VP_SMOOTH_OPT = typer.Option(None, "--vp-smooth", min=0, help="estimated VPs: median over N frames either side of a "
                                                              "sequence (default: the model's rule for images, 2 for "
                                                              "a video)")
VP_SEQUENCES_OPT = typer.Option(None, "--vp-sequences", help="estimated VPs: a frame's sequence (its fallback and "
                                                             "smoothing) is its file name up to the first '_' (name) "
                                                             "or its folder (folder: IDD's drives); default: the "
                                                             "model's rule")
EGO_OPT = typer.Option(None, "--ego", help=EGO_HELP)
BEYOND_OPT = typer.Option(None, "--beyond", help=BEYOND_HELP)
BEV_OPT = typer.Option(False, "--bev", help=BEV_HELP)
QUIET_OPT = typer.Option(False, "--quiet", "-q", help="no progress bar")
OUTPUT_HELP = ("which output: road (P(road), every model) or drivable (P(drivable area): a model trained with 'vctrain "
               "fit --outputs road,drivable', or a graph exported with --output drivable); default: road")
OUTPUT_OPT = typer.Option("road", "--output", help=OUTPUT_HELP)


@app.command("predict")
def predict_cmd(
    checkpoint: Optional[Path] = MODEL_ARG, images: Optional[List[Path]] = IMAGES_ARG, out: Path = OUT_OPT,
    camera: Optional[str] = CAMERA_OPT, prior: Optional[Path] = PRIOR_OPT, store: Optional[Path] = STORE_OPT,
    device: str = DEVICE_OPT, engine: Optional[str] = ENGINE_OPT, keep_store: Optional[Path] = KEEP_STORE_OPT,
    within: str = WITHIN_OPT, overlay: bool = OVERLAY_OPT, mask_video: bool = MASK_VIDEO_OPT,
    vp_range: Optional[Tuple[float, float]] = VP_RANGE_OPT, vp_smooth: Optional[int] = VP_SMOOTH_OPT,
    vp_sequences: Optional[str] = VP_SEQUENCES_OPT, ego: Optional[str] = EGO_OPT, beyond: Optional[str] = BEYOND_OPT,
    bev: bool = BEV_OPT, corridor: float = corridor_option("with --bev: "),
    grid_range: Optional[str] = range_option("with --bev: "), res: float = res_option("with --bev: "),
    threads: Optional[int] = threads_option(), quiet: bool = QUIET_OPT, output: str = OUTPUT_OPT,
):
    """Predict road in original camera images with the checkpoint's own preprocessing.

    A virtual-camera model warps the images into its virtual camera (same scale and completion
    as its training store), infers, and back-projects to the original image; a resize-baseline
    model resizes in and out. With --prior instead of a model, the geometric prior is the
    segmentation (the paper's Table 5 "Geo-Prior" baseline): the images are warped into the
    prior's virtual camera (from its description, e.g. prior.npy.json) and p_g is back-projected.
    Writes OUT/<stem>_mask.png (0/255) and OUT/<stem>_prob.png (0-255 road probability) at the
    image size; prints the mask paths. A video is predicted frame by frame in memory (the same
    numbers), into OUT/<stem>/<stem>_<frame>_mask.png (frame: 6 digits from 0) or, with
    --mask-video, OUT/<stem>_mask.mkv; per-frame VPs are smoothed over time. Images are warped
    as a 'vctrain crossval' study tests them (the same masks): per-frame VPs estimated together
    with the model's rule, the own vehicle's rows cut off, the rectangle extended to hold every
    frame; a frame pixel beyond the training rectangle takes P(road) where the ray from the road VP
    through it leaves that rectangle (--beyond hybrid; extend and rays: docs/predict-eval.md);
    stderr says which VPs, own vehicle and rectangle were used. --bev (every model kind, a resize
    model too, given --camera) adds each frame's road in metres: free_m (how far the --corridor
    ahead is road), width_m at 10, 20 and 30 m (null where not all in view), area_m2 and pose, as
    'vcprep bev' measures them (docs/bev.md). From Python: vctrain.load(MODEL).segment(frame, camera)
    (docs/api.md), the same masks. A model trained with two outputs (road and drivable area) gives
    the one --output names in the masks' place.

    \b
    Example:
      vctrain predict models/road-all/road.pt my/frames --out preds --overlay   # the shipped model
      vctrain predict shipped my/frames --out preds   # the same model by its name, from any folder
      vctrain predict models/road-all/road.pt dashcam/ --ego auto --out preds/dashcam   # bonnet cut off
      vctrain predict runs/vc.pt --camera kitti data/kitti/image_2 --out preds/kitti
      vctrain predict runs/vc.pt --camera low.yaml frames/ --beyond rays --out preds/low   # far below the training camera
      vctrain predict runs/vc.pt --store stores/camvid_val --out preds/camvid_val
      vctrain predict --prior prior.npy --camera kitti data/kitti/image_2 --out preds/geoprior
      vctrain predict runs/vc.pt --camera camvid drive.mp4 --overlay --out preds/drive
      vctrain predict models/road-all/road.pt --camera camvid drive.mp4 --bev --overlay --out preds/drive
      vctrain predict runs/two.pt --camera camvid my/frames --output drivable --out preds/drivable   # two outputs
    """
    from ..predict.inputs import PredictOptions, predict_inputs

    pin_threads(threads)
    options = PredictOptions(
        model=model_arg(checkpoint) if prior is None else checkpoint, images=tuple(images or ()), out=out,
        camera=camera, prior=prior, store=store, device=device, engine=engine, keep_store=keep_store, within=within,
        overlay=overlay, mask_video=mask_video, ego=ego, vp_range=vp_range, vp_smooth=vp_smooth,
        vp_sequences=vp_sequences, beyond=beyond, bev=_bev_options(camera, corridor, grid_range, res) if bev else None,
        progress=not quiet, output=output)
    result = predict_inputs(options, say=None if quiet else (lambda msg: err(f"{out}: {msg}")),
                            note=None if quiet else err)
    _report(result, out, quiet, paths=not bev)


def _bev_options(camera: Optional[str], corridor: float, grid_range: Optional[str], res: float):
    """--bev's settings (:class:`vctrain.predict.bev.BevOptions`): the grid, the corridor, a JSON line a frame."""
    from vcprep.bev import parse_range
    from vcprep.cliutil import emit_json

    from ..predict.bev import BevOptions

    return BevOptions(grid=parse_range(grid_range, res), corridor=corridor, emit=emit_json, spec=camera)


def _report(result, out: Path, quiet: bool, paths: bool = True) -> None:
    """The mask paths on stdout (``paths``; --bev's JSON lines instead); the skipped frames, the summary line and the error of a run with
    skipped frames (exit 1) on stderr."""
    if result.failed and not result.written:  # nothing predicted: the (first) frame's own error
        _failed(result, out)
    for p in result.written if paths else ():
        print(p)
    for line in result.said():
        err(line)
    if not quiet:
        err(f"{out}: {result.startup_line()}")
        err(f"{out}: {result.line()}")
    if result.failed:
        _failed(result, out)


def _failed(result, out: Path) -> None:
    """The error a run with skipped frames ends with (exit 1): one frame's own error, or how many."""
    from vcprep.cliutil import count
    from vcprep.errors import InputError

    done = result.images - len(result.failed)
    others = f"the other {count(done, 'frame')} are written" if done else "nothing written"
    if len(result.failed) == 1:
        file, e = result.failed[0]
        raise InputError(f"{e.problem}; {others}", e.file or file, e.fix)
    if not done:
        file, e = result.failed[0]
        raise InputError(f"{e.problem}; and {count(len(result.failed) - 1, 'other frame')} could not be predicted",
                         e.file or file, e.fix)
    raise InputError(f"{count(len(result.failed), 'frame')} of {result.images} could not be predicted (each named "
                     f"above); {others}", out, "mend or remove those files and run again")


@app.command("export")
def export_cmd(
    checkpoint: Path = typer.Argument(..., help="model written by 'vctrain fit' (virtual-camera or resize baseline), or a "
                                                  f"shipped model's name: shipped (= {SHIPPED})"),
    camera: Optional[str] = typer.Option(None, "--camera", "-c",
                                         help="the camera the graph is for: preset or file (.yaml, KITTI .txt, "
                                              "Cityscapes .json); its image size is the graph's input size (with "
                                              "--frame: that frame's, the camera scaled), its ego_rows are never "
                                              "warped; not needed for a model that reads frames as they are (a "
                                              "resize model: give --frame or --size)"),
    size: Optional[str] = typer.Option(None, "--size", help="WxH: the frame size of a graph exported without "
                                                           "--camera (or give --frame)"),
    out: Path = typer.Option(..., "--out", "-o", help="the ONNX file to write"),
    vp_input: bool = typer.Option(False, "--vp-input", help="the graph takes each frame's road VP (u, v) as a second "
                                                            "input and corrects pan/tilt per frame (else the "
                                                            "camera's mount pose is built in)"),
    pose_range: float = typer.Option(5.0, "--pose-range", min=0.0,
                                     help="with --vp-input: the virtual rectangle holds the camera at pan and tilt "
                                          "within this many degrees of its mount"),
    frame: Optional[Path] = typer.Option(None, "--frame", help="a frame of the camera: the graph is for its image "
                                                               "size (the camera scaled to it; a calibration file "
                                                               "without a size takes it from here)"),
    int8: bool = typer.Option(False, "--int8", help="the network in 8 bits (onnxruntime static quantization, "
                                                    "calibrated on --calib or the shipped examples): faster on a CPU; "
                                                    "stderr gives the share of mask pixels it agrees on with the "
                                                    "float graph"),
    calib: Optional[Path] = typer.Option(None, "--calib", help="with --int8: a folder of the camera's frames to "
                                                              "calibrate on (up to 32 spread over it; default: the "
                                                              "shipped examples)"),
    as_json: bool = typer.Option(False, "--json", help="print the graph's description as one JSON object"),
    threads: Optional[int] = threads_option(),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no summary on stderr"),
    output: str = typer.Option("road", "--output", help="the output the graph computes: road, or drivable (a model "
                                                       "trained with two outputs); recorded in the graph, which "
                                                       "gives no other; default: road"),
):
    """Export a model with its camera inside as one ONNX graph (needs pip install 'vcseg[deploy]').

    The graph takes the camera's raw frame (uint8 H x W x 3 BGR, as cv2.imread gives it, at the
    camera's image size) and returns P(road) (float32 H x W) in the camera's own pixels: inside
    are the warp into the model's virtual camera with the training store's completion, the
    normalisation, the network, softmax and the back-projection -- what 'vctrain predict' does
    for this camera (a resize baseline: resize in and back). A model with two outputs: the graph
    computes the one --output names (P(drivable) with --output drivable), and says so in its metadata. Run it with 'vctrain predict
    OUT.onnx FRAMES --out DIR' or any ONNX runtime. Prints the ONNX path.

    \b
    Example:
      vctrain export runs/vc.pt --camera kitti --frame data/kitti/image_2/000000.png -o road.onnx
      vctrain export runs/vc.pt --camera mycam.yaml --vp-input -o road_vp.onnx
      vctrain export models/road-all/road.pt --frame data/frames/0001.png -o road.onnx
      vctrain export models/road-all/road.pt --size 1280x720 --int8 --calib my/frames -o road_int8.onnx
      vctrain predict road.onnx data/kitti/image_2 --out preds/kitti
      vctrain export runs/two.pt --camera camvid --output drivable -o drivable.onnx   # a two-output model
    """
    from vcprep.cli import camera_for
    from vcprep.cliutil import parse_size
    from vcprep.io import image_size

    from ..deploy.export import export_onnx

    pin_threads(threads)  # (also the check against torch: the graph run in onnxruntime)
    frame_size = image_size(frame) if frame is not None else (parse_size(size, "--size") if size else None)
    cam = None
    if camera is not None:
        cam = camera_for(camera, frame, per_frame=False, quiet=quiet)
        if frame_size is not None and tuple(cam.size) != tuple(frame_size):
            cam = cam.for_image_size(frame_size, frame)  # the same camera at the frames' size (same aspect)
    ensure_parent(out)
    if calib is not None and not int8:
        from vcprep.errors import InputError

        raise InputError("--calib is for --int8", calib, "add --int8, or drop --calib")
    info = export_onnx(model_arg(checkpoint), cam, out, vp_input=vp_input, pose_range=(pose_range, pose_range),
                       size=frame_size, camera_spec=camera, int8=int8, calib=calib, output=output)
    if not quiet:
        _export_summary(info, out, camera, vp_input, int8, frame_size is None)
    path_or_json(out, info, as_json)


def _export_summary(info: dict, out: Path, camera: Optional[str], vp_input: bool, int8: bool, camera_size: bool) -> None:
    """``vctrain export``'s lines on stderr: what the graph holds, its int8 agreement, the one frame size
    it takes (``camera_size``: the camera's, no --frame or --size given)."""
    w, h = info["inputs"]["frame"][1][1], info["inputs"]["frame"][1][0]
    inner = (f"virtual store {info['store_size'][0]}x{info['store_size'][1]}, completion {info['completion']}"
             if info["mode"] == "virtual" else f"resized to {info['work'][0]}x{info['work'][1]}")
    err(f"{out}: {info['mode']} model for camera {info['camera_name']} ({w}x{h}; {inner}; "
        f"{'VP input' if vp_input else 'mount pose built in'}; opset {info['opset']}; onnxruntime vs torch max "
        f"|diff| {info['max_abs_diff_vs_torch']:.1e})")
    if int8:
        q = info["int8"]
        err(f"{out}: int8 network, calibrated on {q['frames']} frames of {q['calibration']}: masks agree with "
            f"the float graph's on {100 * q['mask_agreement']:.2f} % of their pixels")
    if camera_size:
        err(f"{out}: the graph takes {w}x{h} frames only (the size of camera {camera}); for frames of another "
            f"size export with --frame A_FRAME or --size WxH")
