"""How fast? Each stage of the pipeline, the deployed model and prediction under load, each timed
against a baseline in the same run (threads pinned and stated, medians over repeats).

Run one from the repository: ``.venv/bin/python benchmarks/speed/<script>.py`` (``--help`` lists its
options); it writes ``benchmarks/speed/results/`` and ``make docs`` puts that on docs/results.md.
Time: the wall time of one default run where a docstring, docs/development.md or the results JSON
records it, else "unknown".

* ``warp.py`` -- our store warp (one remap, cached maps) against a bare ``cv2.warpPerspective`` of the
  same frames, at 1/8 and full resolution. Results: ``warp.json``. Time: unknown. (``make bench``.)
* ``completion.py`` -- warp + projective completion, and back-projection, against a bare warp of the
  same image to the same size, wall clock and CPU time, with and without torch loaded (issues 4, 81).
  Results: ``completion.json``. Time: about 4 min on 2 loaded cores.
* ``predict_e2e.py`` -- ``vctrain predict`` end to end beside the engine's network alone, in process
  (issue 69), and the whole command in a fresh process at two video lengths: steady-state frames/s
  and start-up apart (issue 81, ``--only whole``). Results: ``predict_e2e.json``,
  ``predict_e2e.whole.json``. Time: unknown (the whole-command part: 20-40 min on 2 loaded cores).
* ``store.py`` -- building a store (``vcprep warp``) with 1 and 2 worker processes against plain PNG
  decode + encode of the same frames. Results: ``store.json``. Time: unknown.
* ``png_deflate.py`` -- the PNG writer with each deflate candidate (zlib, zlib-ng, libdeflate) on a
  store's images, labels, valid masks and frames, against OpenCV's encoder, and whether each gives the
  same bytes in fresh processes (issue 69). Results: ``png_deflate.json``. Time: about 5 min on 2
  loaded cores.
* ``deploy.py`` -- the exported ONNX graph (``vctrain export``) against the torch path per frame, at
  KITTI and BDD100K sizes, 1, 2 threads and the default. Results: ``deploy.json``. Time: unknown.
* ``networks.py`` -- the networks' cost side by side, ``lite0fpn`` against ``resfpn`` (issue 53): a
  frame's prediction and a training step. Results: ``networks.{md,json}``. Time: unknown.
* ``predict_threads.py`` -- ``vctrain predict`` per frame at 1, 2 threads and the default beside 0, 1
  and 2 busy processes (issue 45). Results: ``predict_threads.json``. Time: 4 min
  (docs/development.md).
* ``video.py`` -- video prediction: per-frame VP correction (``within``) against a fixed pose
  (``between``), on a 1-minute 1280x720 video (issue 35). Results: ``video.json``. Time: unknown in
  all; its two end-to-end runs took 119 s and 151 s (video.json).

* ``bev.py`` -- ``vcprep bev``'s per-frame remap onto the KITTI road grid with cached maps against a bare
  ``cv2.remap`` of the same grid, a 1280x720 frame (issue 71); also writes docs/bev.png. Results:
  ``bev.json``. Time: 10 s.

``networks.py`` takes the frames and checkpoints of ``deploy.py`` (``benchmarks.speed.deploy``).
``stages.py`` (each stage's time beside the paper's Table 3) is in ``benchmarks/archive/speed/``, its
``stages.json`` still here (benchmarks/archive/README.md).
"""
