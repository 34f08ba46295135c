"""The own vehicle (bonnet, dashboard) in a folder of one camera's frames, a video's or frames in
memory: one rule (:func:`own_vehicle`), its rows found from the frames where the camera states none.
A virtual-camera model never warps those rows; a model that reads frames as they are predicts 'not
road' on them (:func:`rows_at`)."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import numpy as np

from vcprep.camera import Camera
from vcprep.errors import InputError, VCError
from vcprep.io import image_size

__all__ = ["MISSED_VEHICLE", "own_vehicle", "ego_rows", "frames_ego_rows", "sources_ego_rows", "rows_at",
           "folder_ego_camera", "files_vehicle"]


# said (through ``warn``, even under --quiet) when the search from frames finds no own vehicle: it misses a
# bonnet that reflects the road and one seen from several mounts (Cityscapes': its edge changes sign and
# place from frame to frame; docs/cameras.md), and a missed bonnet is warped as road
MISSED_VEHICLE = ("the search misses a bonnet that reflects the road or sits at several places (frames of "
                  "several mounts), as Cityscapes' does: if the frames show your own vehicle give --ego N (its bottom "
                  "rows) or ego_rows in the camera file; --ego 0 or 'ego_rows: 0' in the camera file says there is "
                  "none and ends this warning")


def own_vehicle(cam: Camera, source: str | Path, ego: str, say: Callable[[str], None] | None,
                estimate: Callable[[], Any], warn: Callable[[str], None] | None = None) -> Camera:
    """``cam`` with its own vehicle's rows (``ego_rows``), one rule for a video and a folder of one
    camera's frames. ``ego``: 'auto' (the camera's ``ego_rows`` when it states them, else found by
    ``estimate()`` -> :class:`vcprep.camera.EgoEstimate` from frames, said through ``say``; too few
    distinct frames: none, also said), 'none' (the camera as given, no search) or a whole number of
    rows at the camera's size (0: no own vehicle). A search that finds none is a warning
    (``warn``, given: the caller's even under --quiet; else ``say``) with :data:`MISSED_VEHICLE`."""
    from dataclasses import replace

    return replace(cam, ego_rows=ego_rows(cam.size[1], cam.ego_rows, source, ego, say, estimate, warn,
                                          known=cam.ego_stated))


def ego_rows(height: int, stated: int, source: str | Path, ego: str, say: Callable[[str], None] | None,
             estimate: Callable[[], Any], warn: Callable[[str], None] | None = None, known: bool = False) -> int:
    """The own vehicle's bottom rows of frames ``height`` rows high by :func:`own_vehicle`'s rule
    (``stated``: the camera's ``ego_rows``, 0 where none is stated; ``known``: the camera file states
    them, an explicit 'ego_rows: 0' too: no search, nothing said)."""
    from vcprep.camera import rows_at_height

    if ego == "none" or (ego == "auto" and (stated or known)):
        return int(stated)
    if ego != "auto":
        try:
            rows = int(ego)
        except ValueError:
            rows = -1
        if not 0 <= rows < height:
            raise InputError(f"--ego '{ego}' is not auto, none or a number of rows below the frames' "
                             f"{height}", source, "give e.g. --ego 40, --ego 0 or --ego none")
        return rows
    say = say or (lambda _msg: None)
    try:
        est = estimate()
    except InputError as e:
        say(f"own vehicle: not looked for ({e.problem}); set ego_rows in the camera file, or --ego N")
        return int(stated)
    if est.rows:
        say(f"own vehicle: {est.rows} rows found from the frames ({est.describe()}); set ego_rows in the "
            f"camera file to override")
    else:
        (warn or say)(f"own vehicle: none found from the frames ({est.describe()}); {MISSED_VEHICLE}")
    return rows_at_height(est, height)


def frames_ego_rows(camera: Camera | None, files: list[Path], ego: str, say: Callable[[str], None] | None = None,
                    warn: Callable[[str], None] | None = None) -> tuple[int, int] | dict[Path, tuple[int, int]]:
    """(rows, frame height) of the own vehicle in a folder of one camera's frames, for a model that
    reads frames as they are: with a camera, :func:`folder_ego_camera`'s; without, by the same rule
    at the first frame's size (``ego`` 'auto' looks in up to :data:`vcprep.io.EGO_SAMPLES` frames
    spread over the folder). Frames of several sources (``ego`` 'auto', no rows stated; a folder per
    drive, BDD100K- or CamVid-style names): each source's own, file -> (rows, height) (:func:`sources_ego_rows`)."""
    if ego == "auto" and not (camera is not None and (camera.ego_rows or camera.ego_stated)):
        per_source = sources_ego_rows(files, say, warn)
        if per_source is not None:
            return per_source
    if camera is not None:
        cam = folder_ego_camera(camera, files, ego, say, warn)
        return cam.ego_rows, cam.size[1]
    from vcprep.camera import ego_rows_from_frame_files

    files = [Path(f) for f in files]
    height = image_size(files[0])[1]
    rows = ego_rows(height, 0, files[0].parent, ego, say,
                    lambda: ego_rows_from_frame_files(_spread(files), files[0].parent), warn)
    return rows, height


def sources_ego_rows(files: list[Path], say: Callable[[str], None] | None = None,
                     warn: Callable[[str], None] | None = None) -> dict[Path, tuple[int, int]] | None:
    """Each source's own vehicle in frames of several sources (:func:`vcprep.camera.ego_rows_per_source`):
    file -> (rows, at height) for the sources searched; the rule and each source's rows said through
    ``say``, a source found without one or not searched (too few frames) through ``warn``. None: one source."""
    from vcprep.camera import GROUP_MIN_DISTINCT, ego_rows_per_source, source_groups
    from vcprep.progress import count
    from vcprep.io import EGO_SAMPLES

    if len(source_groups(files)[1]) < 2:
        return None
    rule, sources = ego_rows_per_source(files, EGO_SAMPLES)
    say, warn = say or (lambda _m: None), warn or say or (lambda _m: None)
    say(f"own vehicle: {count(len(sources), 'source')} grouped by {rule}, each searched alone")
    for s in sources:
        if s.estimate is not None and s.estimate.rows:
            say(f"own vehicle of {s.name} ({count(len(s.files), 'frame')}): {s.estimate.rows} rows found from the "
                f"frames ({s.estimate.describe()})")
        elif s.estimate is not None:
            warn(f"own vehicle of {s.name}: none found ({s.estimate.describe()}); {MISSED_VEHICLE}")
    left = [s for s in sources if s.estimate is None]
    if left:
        names = ", ".join(s.name for s in left[:6]) + (", ..." if len(left) > 6 else "")
        warn(f"own vehicle not searched in {count(len(left), 'source')} of {len(sources)} ({names}; "
             f"{count(sum(len(s.files) for s in left), 'frame')}): fewer than {GROUP_MIN_DISTINCT} distinct frames "
             "each (a single frame cannot show which edge stays put), so nothing is cut there; give --ego N if "
             "they show your own vehicle")
    return {f: (s.estimate.rows, s.estimate.size[1]) for s in sources if s.estimate is not None for f in s.files}


def _spread(files: list[Path]) -> list[Path]:
    """Up to :data:`vcprep.io.EGO_SAMPLES` of ``files``, spread evenly over them (first and last included)."""
    from vcprep.camera import spread
    from vcprep.io import EGO_SAMPLES

    return spread(files, EGO_SAMPLES)


def rows_at(vehicle: tuple[int, int] | None, height: int) -> int:
    """The own vehicle's rows ``vehicle`` = (rows, at height) in a frame ``height`` rows high (rounded up)."""
    if not vehicle or not vehicle[0]:
        return 0
    rows, at = vehicle
    return min(height, int(np.ceil(height * rows / at - 1e-9)))


def folder_ego_camera(camera: Camera, files: list[Path], ego: str = "auto",
                      say: Callable[[str], None] | None = None, warn: Callable[[str], None] | None = None) -> Camera:
    """``camera`` at the frames' size with its own vehicle's rows (:func:`own_vehicle`: 'auto' looks
    in up to :data:`vcprep.io.EGO_SAMPLES` frames spread over the folder, as a video's are). The
    frames' size is the most common among those sampled that the camera takes (a frame of another
    size, or one that cannot be read, is left to the road, which skips and names it); none: the
    first frame's error."""
    from collections import Counter

    from vcprep.camera import ego_rows_from_frame_files

    picks = _spread([Path(f) for f in files])
    sizes: dict[Path, tuple[int, int]] = {}
    for f in picks:
        try:
            sizes[f] = camera.for_image_size(image_size(f), f).size
        except VCError:
            continue
    if not sizes:
        return camera.for_image_size(image_size(picks[0]), picks[0])  # raises: no frame of this camera
    size = Counter(sizes.values()).most_common(1)[0][0]
    cam = camera.for_image_size(size)
    same = [f for f in picks if sizes.get(f) == size]
    return own_vehicle(cam, picks[0].parent, ego, say, lambda: ego_rows_from_frame_files(same, picks[0].parent), warn)


def files_vehicle(predictor: Any, cam: Any, files: list[Path], ego: str | None, say: Callable[[str], None] | None = None,
                  warn: Callable[[str], None] | None = None) -> tuple[Any, Any, str]:
    """(the camera with its own vehicle's rows, the rows a model that reads frames as they are cuts:
    (rows, height) or file -> that per source, where they come from) of one folder's image ``files``
    by ``vctrain predict``'s rules: a model that reads road VPs gets :func:`folder_ego_camera`'s
    camera (``ego`` None: 'auto'); a resize model cuts rows only where ``ego`` asks
    (:func:`frames_ego_rows`); a graph neither."""
    from .frames import reads_frames_as_they_are, reads_road_vps

    one = cam if isinstance(cam, Camera) else None
    if reads_frames_as_they_are(predictor) and ego not in (None, "none"):  # asked for: its own vehicle cut
        rows = frames_ego_rows(one, files, ego, say, warn)
        return cam, rows, f"--ego {ego}" if ego != "auto" else "the camera's ego_rows" if cam and cam.ego_rows else ""
    if reads_road_vps(predictor) and one is not None:  # one camera's frames: its own vehicle, as a video's
        ego = ego or "auto"
        cam = folder_ego_camera(one, files, ego, say, warn)
        stated = one.ego_rows or one.ego_stated  # (an explicit 'ego_rows: 0': none, and no search)
        return cam, None, (f"--ego {ego}" if ego not in ("auto", "none") else "the camera's ego_rows" if stated
                           else "found from the frames" if cam.ego_rows else "")
    return cam, None, ""
