"""What do a camera's own frames say about it? The road vanishing point, the camera's pose and focal
length, and the own vehicle in view, each found from frames and scored against cameras whose
calibration (or labels) we know.

Run one from the repository: ``.venv/bin/python benchmarks/camera_from_frames/<script>.py``
(``--help`` lists its options); it writes ``benchmarks/camera_from_frames/results/`` and ``make docs``
puts that on docs/results.md. Time: the wall time of a default run where a docstring,
docs/development.md or the results JSON records it, else "unknown".

* ``vp.py`` -- the road VP detector against a plain LSD + RANSAC vote, on synthetic frames, CamVid,
  CamVid through three simulated cameras and KITTI; ``--dev`` the development sets only (issue 17).
  Results: ``vp.json``, ``vp.dev.json``. Time: unknown.
* ``camera_estimate.py`` -- how well ``vcprep camera estimate`` recovers cameras whose calibration we
  know and hide: horizon, tilt, pan, focal length, road depth scale (issue 25). Results:
  ``camera_estimate.{md,json}``. Time: unknown.
* ``ego_frames.py`` -- the own vehicle found from frames alone against the label method, on the real
  sets (issue 35). Results: ``ego_frames.json``. Time: 40 s (docs/development.md; ego_frames.json:
  36.3 s).

``focal_from_verticals.py`` (can the frames fix the focal length? no: issue 25) is in
``benchmarks/archive/camera_from_frames/``, its results still here (benchmarks/archive/README.md).
"""
