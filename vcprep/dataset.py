"""Datasets on disk: find the images of a folder tree, pair them with their labels, name the items.

Three entry points, one rule for what an image file is (:data:`vcprep.io.images.IMAGE_EXTENSIONS`,
names starting with '.' skipped, subfolders included, sorted by relative path):

- :func:`find_images`: every image file under one folder;
- :func:`list_dataset`: the jobs of a store build (``--images`` with ``--labels`` in a mirrored
  tree, ids from the label format's naming rule);
- :func:`collect_images`: image arguments as a command gets them (files as given, folders
  expanded), ids = file stems; used by ``vcprep vp``/``camera estimate``/``figure camera`` and
  ``vctrain predict``/``adapt``.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable

from .errors import InputError
from .io.images import IMAGE_EXTENSIONS
from .labels import LabelFormat, image_id, label_stem_for

__all__ = ["Job", "find_images", "list_dataset", "collect_images", "OUTPUTS_BY_STEM"]


@dataclass(frozen=True)
class Job:
    """One item to build: its id, source image and (optional) source label."""

    id: str
    image: Path
    label: Path | None = None


def find_images(folder: str | Path, kind: str = "image", skip: Path | None = None) -> list[Path]:
    """Every image file under ``folder``, recursively (dataset trees such as Cityscapes'
    ``leftImg8bit/train/<city>/``), sorted by path relative to ``folder``; names starting with
    '.' (files and folders) are skipped, symbolic links to folders followed (each real folder
    once), and ``skip`` (e.g. a label tree inside the image tree) left out."""
    folder = Path(folder)
    if not folder.exists():
        raise InputError(f"{kind} folder not found", folder, f"check the {kind} folder path")
    if not folder.is_dir():
        raise InputError(f"is a file, expected a folder of {kind}s", folder, f"give the folder that holds the {kind}s")
    skip_real = os.path.realpath(skip) if skip is not None else None
    seen: set[str] = set()
    files: list[Path] = []
    for top, dirs, names in os.walk(folder, followlinks=True):
        real = os.path.realpath(top)
        if real in seen or real == skip_real:
            dirs[:] = []
            continue
        seen.add(real)
        dirs[:] = [d for d in dirs if not d.startswith(".")]
        files += [Path(top) / n for n in names
                  if not n.startswith(".") and os.path.splitext(n)[1].lower() in IMAGE_EXTENSIONS]
    return sorted(files, key=lambda f: f.relative_to(folder).parts)


def _images_in(folder: Path, skip: Path | None = None) -> list[Path]:
    files = find_images(folder, skip=skip)
    if not files:
        raise InputError(f"no images ({', '.join(IMAGE_EXTENSIONS)}) in folder or its subfolders", folder,
                         "check --images")
    return files


def _inside(path: Path, folder: Path) -> bool:
    try:
        Path(os.path.realpath(path)).relative_to(os.path.realpath(folder))
        return True
    except ValueError:
        return False


def list_dataset(images: str | Path, labels: str | Path | None = None, fmt: LabelFormat | None = None,
                 id_prefix: str = "") -> list[Job]:
    """Jobs for every image in the tree ``images`` (recursively, :func:`find_images`); with
    ``labels``, each image's label is found in the mirrored tree: the same subfolder of
    ``labels``, named by the format's naming rule (``labels.LABEL_FORMATS``; Cityscapes
    ``leftImg8bit/train/<city>/X_leftImg8bit.png`` -> ``gtFine/train/<city>/X_gtFine_labelIds.png``).
    A missing label is an error; ids are file stems, and two images with one id are an error."""
    images = Path(images)
    label_dir = Path(labels) if labels is not None else None
    if not images.is_dir():  # the images first: with both folders missing, the images are what to fix first
        find_images(images)
    if label_dir is not None:
        if fmt is None:
            raise InputError("labels given without a label format", label_dir, "add --label-format (e.g. camvid)")
        if not label_dir.is_dir():
            raise InputError("label folder not found" if not label_dir.exists() else "is not a folder", label_dir,
                             "check --labels")
    files = _images_in(images, skip=label_dir if label_dir is not None and _inside(label_dir, images) else None)
    label_files: dict[tuple[tuple[str, ...], str], Path] = {}
    if label_dir is not None:
        for p in find_images(label_dir, "label"):
            label_files.setdefault((p.relative_to(label_dir).parent.parts, p.stem), p)
    jobs: list[Job] = []
    seen: dict[str, Path] = {}
    for f in files:
        iid = id_prefix + image_id(f, fmt)
        if iid in seen:
            raise InputError(f"duplicate image id '{iid}' (also {seen[iid].relative_to(images)})", f,
                             "give each image a unique file name stem (ids are file stems, also in subfolders)")
        seen[iid] = f
        lab = None
        if label_dir is not None:
            stem = label_stem_for(f, fmt)
            sub = f.relative_to(images).parent
            lab = label_files.get((sub.parts, stem))
            if lab is None:
                raise InputError(f"no label '{sub / stem}.png' for this image in {label_dir}", f,
                                 "check --labels (a tree mirroring --images) and --label-format, or remove the image")
        jobs.append(Job(iid, f, lab))
    return jobs


# why the ids of collect_images must be unique, as (problem, fix): the outputs are named by stem
OUTPUTS_BY_STEM = ("two images named", "outputs are named by stem; predict them into separate --out folders")


def collect_images(paths: Iterable[str | Path], unique: tuple[str, str] | None = OUTPUTS_BY_STEM,
                   missing: str = "image not found", trees: bool = False) -> list[Job]:
    """Jobs (id = file stem) for image files as given and every image inside given folders (and
    their subfolders, :func:`find_images`), in argument order.

    ``unique``: two images with one id are an error, said as ``(problem, fix)``
    ("<problem> '<id>' (also <path>)"); None allows them. ``missing``: the problem of a path
    that does not exist. ``trees``: a folder whose subfolders repeat file names (IDD's drives,
    ``<drive>/<frame>.png``) gives each of its images its path below the folder as its id
    (``drive1/000123``, '/' separated, no suffix): outputs named by id mirror the tree."""
    jobs: list[Job] = []
    seen: dict[str, Path] = {}
    for p in map(Path, paths):
        if p.is_dir():
            files = find_images(p)  # recursively: dataset trees such as Cityscapes' leftImg8bit/<split>/<city>/
            if not files:
                raise InputError("no images in folder", p, f"give image files ({', '.join(IMAGE_EXTENSIONS)})")
        elif p.exists():
            files = [p]
        else:
            raise InputError(missing, p, "check the path")
        tree = trees and p.is_dir() and len({f.stem for f in files}) < len(files)
        for f in files:
            iid = f.relative_to(p).with_suffix("").as_posix() if tree else f.stem
            if unique is not None and iid in seen:
                raise InputError(f"{unique[0]} '{iid}' (also {seen[iid]})", f, unique[1])
            seen.setdefault(iid, f)
            jobs.append(Job(iid, f))
    if not jobs:
        raise InputError("no images given", None, "give image files or folders")
    return jobs
