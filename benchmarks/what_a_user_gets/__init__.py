"""What does a user get? The model the project ships, the README's own route (warp, fit, predict with
no flag set by hand), fine-tuning the shipped model on a few frames of one's own camera, and a
model trained and tested in one camera.

Run one from the repository: ``.venv/bin/python benchmarks/what_a_user_gets/<script>.py`` (``--help``
lists its options); it writes ``benchmarks/what_a_user_gets/results/`` and ``make docs`` puts that on
docs/results.md (the README's headline and its first hour take ``shipped_model.json``,
``shipped_model_e60.json`` and ``shipped_model.png``). Models and stores go to
``benchmarks/out/<script>/`` (not in git). Time: the wall time of a default run where a docstring,
docs/development.md or the results JSON records it, else "unknown".

* ``shipped_model.py`` -- the shipped road model (``models/road-multicamera``): one model trained on
  every development set's training split, scored on each held-out split and the KITTI frame, against
  its twin (issue 34; ``--ship`` writes the model folder and ``shipped_model.png``). Results:
  ``shipped_model.{md,json,png}`` and ``shipped_model_<variant>.{md,json}`` (``_e60``: both twins at
  60 epochs). Time: about 33 min a model (shipped_model.json: 33.28, lite0fpn, 30 epochs).
* ``user_route.py`` -- the route a user follows, as the README writes it: does ``vcprep warp`` +
  ``vctrain fit`` with no flag set by hand deliver what ``vctrain crossval`` measured for the same
  frames (issue 52)? Results: ``user_route.{md,json}``. Time: unknown.
* ``own_frames.py`` -- a user's own labelled frames (issue 60): the shipped model as it is, fine-tuned
  with ``vctrain fit --init``'s defaults, with the command the card gave before, or trained on them from
  ImageNet, for 20, 60 and 200 frames of IDD-Lite, with the shipped model (a camera it knows) and with
  the shipped recipe trained without IDD-Lite (one it never saw). Results:
  ``own_frames_idd_{shipped,unseen}.{md,json}``. Time: about 2-3 min a fit of 60 frames, 8 of 200, plus
  the base model (about 30 min).
* ``finetune_guard.py`` -- fine-tuning the shipped model that never leaves a user worse off (issue 72):
  ``fit --init``'s held-out guard and recipe variants on CamVid's dusk drive (scored on the daylight
  drive) and on KITTI (a camera the model never saw), against zero-shot. Results:
  ``finetune_guard[_<tag>].{md,json}``. Time: 5-8 min a 4-epoch fit of 60 frames on 2 shared cores,
  20-25 min a 20-epoch one.
* ``label_check.py`` -- labels read as the wrong class (issue 80): ``vctrain fit``'s label check on the
  seven real label sets with their right formats, as frames and as stores of the README's route (none
  refused), and on CamVid's labels read with ``values:road=1;ignore=255`` (building as road: refused).
  Results: ``label_check.{md,json}``. Time: about 3 min on 2 shared cores.

* ``bev_metres.py`` -- the road in metres a planner gets (issue 80): ``free_m`` and ``width_m`` (10,
  20 m) from a model's masks (``--model``, default the shipped one) against the same from the labels,
  the rules before issue 80 against today's, on the 98 kitti_semantics frames (each frame's VP pose
  and the nominal one) and the KITTI road frame. Results: ``bev_metres[_<tag>].{md,json}``. Time:
  about 35 s (one thread; the masks cached in ``benchmarks/out/bev_metres/``).

``shipped_model.py`` runs its study with ``benchmarks.measure.studies`` (as
``benchmarks/other_cameras/as_shipped.py`` does), and ``user_route.py`` compares with its
``as_shipped.json``.

The closed studies of this question (``finetune.py``: the learning-rate rule before ``fit --init``'s
defaults; ``shipped_screen.py``: larger encoders against the shipped recipe; ``train.py``: CamVid in
its own camera) are in ``benchmarks/archive/what_a_user_gets/``, their results still here:
benchmarks/archive/README.md says what each answered.
"""
