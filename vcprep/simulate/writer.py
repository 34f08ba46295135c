"""Simulating another camera, exactly: a new dataset as if shot by a re-mounted, re-zoomed,
re-cropped camera at the same place.

Rotating a pinhole camera about its optical centre changes the image by the homography
``out_H_src = K' R K^-1`` for ANY scene (no flat-road assumption), and zooming or cropping only
changes K. So a dataset can be re-rendered exactly for another pan, tilt, roll, focal length,
image size and principal point. A change of mounting HEIGHT moves the optical centre: it needs
the depth of every pixel and cannot be simulated exactly from one image, so it is not offered.

Conventions (``../shared/docs/method.md``): pixels (u, v) with the origin at the centre of the
top-left pixel; camera frame x right, y down, z forward; ``tilt`` > 0 = pitched down, ``pan``
about the vertical axis after the tilt. Rotations:

* ``Rw(pan, tilt) = column_stack(pose_axes(pan, tilt))`` takes world directions to camera
  directions (its columns are the world axes in camera coordinates);
* a source of nominal pose (pan0, tilt0) re-mounted at (pan0 + dpan, tilt0 + dtilt) and rolled by
  ``roll`` has the camera-frame rotation ``R = Rroll(roll) @ Rw(pan0 + dpan, tilt0 + dtilt) @
  Rw(pan0, tilt0).T``: a direction d in the source camera frame is ``R @ d`` in the new one;
* ``Rroll(r) = [[cos r, -sin r, 0], [sin r, cos r, 0], [0, 0, 1]]``: **positive roll turns the
  picture clockwise on screen** (a point right of the principal point moves down; the right end
  of the horizon drops), i.e. the camera itself rolls counter-clockwise as seen from behind it.

Output camera: ``fx' = zoom*fx``, ``fy' = zoom*fy`` (pixel aspect kept), principal point at the
output image centre ``((W'-1)/2, (H'-1)/2 + horizon_shift)``. With ``flip`` the output is
mirrored left-right (``u -> W'-1-u``); the camera stays a pinhole with ``cx' -> W'-1-cx'`` (the same
value, it is central) in a mirrored world: pan and roll change sign, tilt is kept.

Vanishing points: the output VP of an image is ``out_H_src`` applied to the SOURCE image's road VP
(from a CSV ``id,u,v`` or, without one, the source camera's nominal-pose VP). The per-image
change is exact; the absolute VP is as good as the source VP.

Three layers (style.md), every name importable from here: pure geometry
(:mod:`vcprep.simulate.geometry`: :func:`relative_rotation`, :func:`output_camera`,
:func:`widest_zoom`, ...), :func:`plan_simulation` (:mod:`vcprep.simulate.plan`: every image's H, VP
and pose, all inputs checked, nothing written) and, here, :func:`simulate_dataset` (reads, warps,
writes atomically).
"""
from __future__ import annotations

import csv
import hashlib
import io
import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Sequence

import cv2
import numpy as np

from vcprep import __version__
from ..dataset import Job
from ..camera.pinhole import Camera
from ..camera.files import camera_to_yaml
from ..errors import GeometryError, InputError
from ..io.images import read_image, write_bytes_atomic, write_png
from ..labels import LabelFormat, decode_label
from .plan import SimItem, SimPlan, SimulateParams, plan_simulation


SIM_ALGORITHM = "simulate-v1"  # bump when outputs of identical inputs would change


@dataclass
class SimSummary:
    out: Path
    total: int = 0
    written: int = 0
    up_to_date: int = 0
    removed: int = 0
    zoom: float = 1.0
    fov_deg: tuple[float, float] = (0.0, 0.0)
    fov_auto: bool = False
    size: tuple[int, int] = (0, 0)
    notes: list[str] = field(default_factory=list)

    def line(self) -> str:
        how = "widest covered" if self.fov_auto else "given"
        return (f"{self.total} images: {self.written} written, {self.up_to_date} up to date; "
                f"{self.size[0]}x{self.size[1]}, hfov {self.fov_deg[0]:.2f} deg ({how}), "
                f"vfov {self.fov_deg[1]:.2f} deg, zoom {self.zoom:.4f}"
                + (f"; {self.removed} outputs of images no longer given removed" if self.removed else ""))


# --- one image in memory ----------------------------------------------------------------------

def simulate_arrays(image: np.ndarray, label: np.ndarray | None, out_H_src: np.ndarray, out_size: tuple[int, int],
                    greyscale: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
    """Warp one image (bilinear, any depth/channels) and its raw label (nearest: ids or colours
    kept) through ``out_H_src`` to ``out_size``. Every output pixel must be covered (see
    :func:`covered`); ``greyscale`` gives a 3-channel grey image."""
    from ..warp.remap import maps_for, warp_image, warp_label

    h, w = image.shape[:2]
    maps = maps_for(out_H_src, (w, h), tuple(out_size))
    if not maps.valid.all():
        raise GeometryError("the simulated view reaches outside the source image", None,
                            "plan the simulation with plan_simulation, which checks coverage")
    img = warp_image(image, maps)
    if greyscale:
        g = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img
        img = cv2.merge([g, g, g])
    lab = warp_label(label, maps) if label is not None else None
    return img, lab


# --- the dataset driver -----------------------------------------------------------------------

def _sha(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def _csv(header: list[str], rows: list[list[Any]]) -> bytes:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    return buf.getvalue().encode()


def _params_dict(plan: SimPlan, fmt: LabelFormat | None, vps_file) -> dict[str, Any]:
    p = asdict(plan.params)
    p["size"] = list(plan.camera.size)
    return {**p, "label_format": fmt.name if fmt else None, "vps": str(vps_file) if vps_file else None}


def _item_key(plan: SimPlan, item: SimItem, img_sha: str, lab_sha: str | None, fmt: LabelFormat | None) -> str:
    parts = {"algorithm": SIM_ALGORITHM, "camera": plan.camera.to_dict(), "greyscale": plan.params.greyscale,
             "H": [float(x) for x in item.out_H_src.ravel()], "image": img_sha, "label": lab_sha,
             "label_format": fmt.name if fmt else None}
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def recorded_homographies(out: str | Path) -> dict[str, np.ndarray]:
    """{item id: out_H_src (3, 3)} of a finished ``vcprep simulate`` output folder, read from its
    ``simulate.json``: the exact map from each source frame's pixels to its simulated frame's
    (pixel centres, origin at the top-left pixel's centre), e.g. to carry anything computed on a
    source frame (a prediction, a detected VP) into the simulated camera. A missing, unfinished or
    unreadable record raises :class:`InputError`."""
    meta = Path(out) / "simulate.json"
    try:
        doc = json.loads(meta.read_text())
        if not doc.get("complete"):
            raise InputError("the simulation is unfinished", meta, "run the same 'vcprep simulate' again")
        return {str(r["id"]): np.asarray(r["out_H_src"], dtype=np.float64).reshape(3, 3) for r in doc["items"]}
    except FileNotFoundError:
        raise InputError("no simulate.json", meta, "give the folder of a 'vcprep simulate' output") from None
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as e:
        raise InputError(f"unreadable simulation record ({e.__class__.__name__}: {e})", meta,
                         "run the same 'vcprep simulate' again") from None


def _prepare_out(out: Path) -> dict[str, dict]:
    """Check OUT is new, empty or an earlier simulate output; return its earlier item records."""
    if out.exists() and not out.is_dir():
        raise InputError("exists and is not a folder", out, "give a new folder for --out")
    meta = out / "simulate.json"
    if out.is_dir() and any(out.iterdir()) and not meta.is_file():
        raise InputError("folder is not empty and holds no simulate.json", out,
                         "give a new or empty folder, or the folder of an earlier 'vcprep simulate'")
    if not meta.is_file():
        return {}
    try:
        old = json.loads(meta.read_text())
        return {r["id"]: r for r in old.get("items", []) if isinstance(r, dict) and "id" in r}
    except (OSError, ValueError, AttributeError, TypeError):
        return {}


def simulate_dataset(jobs: Sequence[Job], camera: Camera, out: str | Path, params: SimulateParams,
                     fmt: LabelFormat | None = None, vps_file: str | Path | None = None,
                     progress: bool = True) -> tuple[SimPlan, SimSummary]:
    """Write the simulated dataset to ``out``: ``images/<stem>.png``, ``labels/<label name>.png``
    (raw values), ``camera.yaml``, ``vps.csv`` (id,u,v output pixels), ``poses.csv``
    (id,pan_deg,tilt_deg,roll_deg: pan/tilt of the output image's road VP through the output
    camera, plus its roll) and ``simulate.json`` (parameters, cameras, zoom, per-image H, hashes).

    Everything is checked before anything is written; files are written atomically. Re-running
    with the same inputs skips the images whose recorded outputs are unchanged; outputs of images
    no longer in the input are removed (OUT holds exactly one simulated dataset)."""
    from tqdm import tqdm

    from ..vp.reliability import read_vp_csv

    out = Path(out)
    for j in jobs:
        for src, sub in ((j.image, "images"), (j.label, "labels")):
            if src is not None and src.parent.resolve() == (out / sub).resolve():
                raise InputError("--out would overwrite the source files", out, "give another folder for --out")
    vps = read_vp_csv(vps_file) if vps_file is not None else None
    labelled = [j.label for j in jobs if j.label is not None]
    if labelled and fmt is None:
        raise InputError("labels given without a label format", labelled[0], "add --label-format (e.g. camvid)")
    plan = plan_simulation(jobs, camera, params, vps, vps_file, out_name=out.name or "simulated")
    old = _prepare_out(out)
    cam = plan.camera
    img_dir, lab_dir = out / "images", out / "labels"
    has_labels = any(it.job.label is not None for it in plan.items)
    out.mkdir(parents=True, exist_ok=True)
    img_dir.mkdir(exist_ok=True)
    if has_labels:
        lab_dir.mkdir(exist_ok=True)

    summary = SimSummary(out, total=len(plan.items), zoom=plan.zoom, fov_deg=plan.fov_deg, fov_auto=plan.fov_auto,
                         size=cam.size, notes=list(plan.notes))
    records: dict[str, dict] = {}

    def meta(complete: bool) -> None:
        recs = [records.get(it.job.id) or old.get(it.job.id) for it in plan.items]
        hf, vf = plan.fov_deg
        doc = {"format": "vcprep-simulate", "version": 1, "tool_version": __version__, "algorithm": SIM_ALGORITHM,
               "complete": complete, "parameters": _params_dict(plan, fmt, vps_file),
               "source_camera": plan.source.to_dict(), "camera": cam.to_dict(), "zoom": plan.zoom,
               "fov_deg": [hf, vf], "fov_auto": plan.fov_auto,
               "counts": {"images": len(plan.items), "labels": sum(it.job.label is not None for it in plan.items),
                          "written": summary.written, "up_to_date": summary.up_to_date},
               "items": [r for r in recs if r is not None]}
        write_bytes_atomic(out / "simulate.json", (json.dumps(doc, indent=1) + "\n").encode())

    # the marker first (OUT is ours from now on), then the files that need only the geometry
    meta(False)
    write_bytes_atomic(out / "camera.yaml", camera_to_yaml(cam).encode())
    write_bytes_atomic(out / "vps.csv", _csv(["id", "u", "v"], [[it.job.id, f"{it.vp[0]:.9f}", f"{it.vp[1]:.9f}"]
                                                                for it in plan.items]))
    write_bytes_atomic(out / "poses.csv", _csv(["id", "pan_deg", "tilt_deg", "roll_deg"],
                                               [[it.job.id] + [f"{x:.9f}" for x in it.pose] for it in plan.items]))
    # OUT holds exactly this dataset: drop outputs of images no longer given and stray temp files
    keep = {img_dir / f"{it.job.image.stem}.png" for it in plan.items}
    keep |= {lab_dir / f"{it.job.label.stem}.png" for it in plan.items if it.job.label is not None}
    for d in (img_dir, lab_dir):
        if d.is_dir():
            for f in d.iterdir():
                if f.is_file() and f not in keep and (f.suffix == ".png" or f.name.endswith(".tmp")):
                    f.unlink()
                    summary.removed += 1

    bar = tqdm(total=len(plan.items), desc="simulate", unit="img", disable=None if progress else True, leave=False)
    try:
        for it in plan.items:
            records[it.job.id] = _simulate_item(it, plan, fmt, img_dir, lab_dir, old.get(it.job.id), summary)
            bar.update()
    except BaseException:
        meta(False)  # keep what is finished, so that re-running skips it
        raise
    finally:
        bar.close()
    meta(True)
    return plan, summary


def _simulate_item(it: SimItem, plan: SimPlan, fmt: LabelFormat | None, img_dir: Path, lab_dir: Path,
                   old: dict | None, summary: SimSummary) -> dict:
    job = it.job
    try:
        img_bytes = job.image.read_bytes()
        lab_bytes = job.label.read_bytes() if job.label is not None else None
    except OSError as e:
        raise InputError(f"cannot read: {e.strerror or e}", e.filename, "check the file") from None
    img_sha = hashlib.sha256(img_bytes).hexdigest()
    lab_sha = hashlib.sha256(lab_bytes).hexdigest() if lab_bytes is not None else None
    key = _item_key(plan, it, img_sha, lab_sha, fmt)
    out_img = img_dir / f"{job.image.stem}.png"
    out_lab = lab_dir / f"{job.label.stem}.png" if job.label is not None else None
    if (old is not None and old.get("key") == key and _sha(out_img) == old.get("out_image_sha256")
            and (out_lab is None or _sha(out_lab) == old.get("out_label_sha256"))):
        summary.up_to_date += 1
        return old
    img = read_image(job.image).array
    if img.shape[1::-1] != it.size:
        raise InputError(f"image is {img.shape[1]}x{img.shape[0]}, its header said {it.size[0]}x{it.size[1]}",
                         job.image, "re-copy or re-export the file")
    lab = None
    if job.label is not None:
        lab = read_image(job.label, label=True).array
        if lab.shape[:2] != img.shape[:2]:
            raise InputError(f"label is {lab.shape[1]}x{lab.shape[0]} but its image is {img.shape[1]}x{img.shape[0]}",
                             job.label, "give the label that belongs to this image")
        decode_label(lab, fmt, job.label)  # refuse labels the format cannot read (the output keeps raw values)
    wimg, wlab = simulate_arrays(img, lab, it.out_H_src, plan.camera.size, plan.params.greyscale)
    img_out_sha = write_png(out_img, wimg)
    lab_out_sha = write_png(out_lab, wlab, kind="mask") if wlab is not None else None
    summary.written += 1
    return {"id": job.id, "image": str(job.image), "image_sha256": img_sha,
            "label": str(job.label) if job.label is not None else None, "label_sha256": lab_sha,
            "draw_deg": list(it.draw), "out_H_src": [float(x) for x in it.out_H_src.ravel()],
            "vp_source": list(it.vp_source), "vp_status": it.vp_status, "vp": list(it.vp),
            "pose_deg": list(it.pose), "out_image": f"images/{out_img.name}", "out_image_sha256": img_out_sha,
            "out_label": f"labels/{out_lab.name}" if out_lab is not None else None, "out_label_sha256": lab_out_sha,
            "key": key}
