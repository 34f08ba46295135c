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
* ``real_cameras.py`` -- the simulated study: CamVid-trained models on KITTI and three cameras cut
  exactly from CamVid (a development aid, not the verdict; issue 14). Results:
  ``real_cameras.{md,json,png}``, ``real_cameras_within_seq_fallback.{md,json}``. Time: 9 models x
  about 4.6 min (real_cameras.json) plus a few minutes of stores and testing (its docstring).
* ``cross_camera.py`` -- four exact cameras cut from CamVid, leave one out, five conditions (paper
  Tables 4/7). Results: ``cross_camera.{md,json,csv,png}``, ``cross_camera_runs.jsonl``. Time: about
  50 min (docs/development.md).
* ``multi_camera.py`` -- **several cameras merged**: each of the five real datasets held out in turn,
  one model trained on the other four (issue 34). Results: ``multi_camera.{md,json}`` (``extent:
  max``), ``multi_camera_median.{md,json}`` (``--extent median``), ``multi_camera_<model>*.{md,json}``.
  Time: about 9 min a model (multi_camera_median.json: 8.79; multi_camera.json: 9.82); the total is
  not recorded.
* ``merged_estimated.py`` -- **several cameras merged, no guessed camera file**: ``multi_camera.py
  --extent median`` with IDD-Lite's, BDD100K's and LUMS's cameras estimated (training sets from frames
  and labels, the held-out set from its frames only, as ``vctrain predict --camera estimate``), one
  study per fold, lite0fpn (issue 59). Results: ``merged_estimated.{md,json}``. Time: the folds run so
  far in merged_estimated.json (``minutes_per_model``), two models a fold and seed.
* ``calibrated_loo.py`` -- **the calibrated leave-one-out**: CamVid, Cityscapes and KITTI
  (``kitti_semantics``), the three calibrated cameras, each held out in turn and trained on the other
  two; IDD-Lite, BDD100K and LUMS test-only in every fold, with their assumed files and estimated from
  their frames; ``within`` against ``resize``, ``--model`` resfpn or lite0fpn (issue 73). Results:
  ``calibrated_loo_<model>.{md,json}``. Time: two models a fold and seed; ``minutes_per_model`` in the JSON.
* ``multi_camera_candidates.py`` -- issue 44's candidates for a camera-aware model that wins when
  cameras are merged, one table over the finished folds (it trains nothing). Results:
  ``multi_camera_candidates.{md,json}``. Time: unknown.
* ``multi_camera_ensembles.py`` -- is condition ``average`` the geometry or just an ensemble? Its
  control on the same folds (issue 44). Results: ``multi_camera_ensembles.{md,json}``. Time: unknown.
* ``loo_diagnose.py`` -- where the virtual camera loses a held-out camera: one fold of
  ``multi_camera.py`` taken apart pixel by pixel (issue 34). Results:
  ``loo_diagnose_<held-out>.{md,json}``. Time: unknown.
* ``adapt_loo.py`` -- adapting to a held-out camera without its labels: the geometric prior against
  self-training, on the losing folds (issue 34). Results: ``adapt_loo.{md,json}``. Time: unknown.

``multi_camera.py`` (and through it ``merged_estimated.py`` and ``calibrated_loo.py``) and ``benchmarks/what_a_user_gets/shipped_model.py`` build their studies with
``as_shipped.py``'s (``benchmarks.other_cameras.as_shipped``; the shipped model also takes
``multi_camera.py``'s shading augmentation); ``multi_camera_ensembles.py`` takes
``multi_camera_candidates.py``'s folds; ``loo_diagnose.py``, ``adapt_loo.py`` and the candidates read the
models ``multi_camera.py`` left in ``benchmarks/out/multi_camera/``.
"""
