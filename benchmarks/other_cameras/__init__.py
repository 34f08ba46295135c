"""Does a model carry to cameras it was not trained on? Trained on one camera and tested on real
others; trained on several cameras merged with one held out in turn; and what a held-out camera's
unlabelled frames can add. Road IoU in each test camera's own pixels, the virtual camera
(``within``) against the same network on resized images (``resize``), mean ± std over seeds.

Run one from the repository: ``.venv/bin/python benchmarks/other_cameras/<script>.py`` (``--help``
lists its options); it writes ``benchmarks/other_cameras/results/`` and ``make docs`` puts that on
docs/results.md (the README's headline takes ``as_shipped.json`` and ``multi_camera_median.json``).
Models and stores go to ``benchmarks/out/<script>/`` (not in git), where an interrupted run resumes.
Time: the wall time of a default run where a docstring, docs/development.md or the results JSON
records it, else "unknown"; a study's total is its models times the minutes a model.

* ``as_shipped.py`` -- **one training camera, the verdict**: trained on CamVid with ``vctrain
  crossval``'s defaults, tested on five real other cameras as they ship; own vehicle, estimated
  cameras, leave one real dataset out (issues 24, 25). Results: ``as_shipped.{md,json,png}`` (and
  ``as_shipped_<model>.{md,json}`` of ``--model`` runs). Time: about 7 min a model
  (as_shipped.json: 6.88); the total is not recorded.
* ``multi_camera.py`` -- **several cameras merged**: each of the five real datasets held out in turn,
  one model trained on the other four (issue 34). Results: ``multi_camera.{md,json}`` (``extent:
  max``), ``multi_camera_median.{md,json}`` (``--extent median``), ``multi_camera_<model>*.{md,json}``.
  Time: about 9 min a model (multi_camera_median.json: 8.79; multi_camera.json: 9.82); the total is
  not recorded.
* ``calibrated_loo.py`` -- **the calibrated leave-one-out**: CamVid, Cityscapes and KITTI
  (``kitti_semantics``), the three calibrated cameras, each held out in turn and trained on the other
  two; IDD-Lite, BDD100K and LUMS test-only in every fold, with their assumed files and estimated from
  their frames; ``within`` against ``resize``, ``--model`` resfpn or lite0fpn (issue 73). Results:
  ``calibrated_loo_<model>.{md,json}``. Time: two models a fold and seed; ``minutes_per_model`` in the JSON.

Every study here and ``benchmarks/what_a_user_gets/``'s run ``vctrain crossval`` through
``benchmarks.measure.studies`` (a study file, its run resumed, the stores shared between seeds, the
CamVid model's step budget; it began in ``as_shipped.py``, whose figures and page are in
``benchmarks.measure.as_shipped_figures``). ``multi_camera.py`` (and through it
``calibrated_loo.py``) and ``benchmarks/what_a_user_gets/shipped_model.py`` take the CamVid step budget
(the shipped model also takes ``multi_camera.py``'s shading augmentation); ``calibrated_loo.py`` takes its folds' command line and the
frames-only cameras from ``benchmarks.measure.folds``.

The closed studies of this question (the simulated cameras, the cut CamVid cameras, issue 44's
candidates and their ensemble control, the LOO diagnosis and label-free adaptation, the merged study
with estimated cameras, the low camera, the camera file's error, the BEV's worth) are in
``benchmarks/archive/other_cameras/``, their results still here: benchmarks/archive/README.md says what
each answered.
"""
