"""The benchmarks, in folders named by the question they answer (each folder's ``__init__.py`` lists
its scripts, the question each answers, the results it writes and the time it takes):

* ``speed/`` -- how fast is each stage, the deployed model, prediction under load?
* ``other_cameras/`` -- does a model carry to cameras it was not trained on (one training camera,
  several merged, adapted without labels)?
* ``camera_from_frames/`` -- what do a camera's own frames say about it (road VP, pose, focal length,
  own vehicle)?
* ``what_a_user_gets/`` -- the shipped model, the README's route, fine-tuning on one's own camera.
* ``archive/<question>/`` -- closed studies, out of the live suite: their questions are answered and
  frozen in the docs, their results stay in ``<question>/results/`` (``archive/README.md`` says what
  each answered and where its result lives).

At the top only what a developer runs to check a change: ``results_page.py`` (``make docs``: the
results page and the README's headline from every ``<question>/results/*.json``; ``--check`` says
whether they are stale) and ``make bench`` (``speed/warp.py``). ``measure/`` is the code the scripts
share. Each script writes its results to ``results/`` beside it (``measure.report.results_dir``) and
keeps its models, stores and caches under ``benchmarks/out/<name>/`` (not in git).

Every script runs as a file from the repository: ``.venv/bin/python benchmarks/<question>/<name>.py``.
Its one ``sys.path`` line puts the repository first, so it imports this package by its full name
(``benchmarks.measure.data``, ``benchmarks.measure.studies``) as well as the repository's own
``vcprep`` and ``vctrain``.
"""
