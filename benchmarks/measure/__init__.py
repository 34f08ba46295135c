"""Shared measuring code of the benchmarks, one module per topic; every script under
``benchmarks/<question>/`` imports what it needs from these (``from benchmarks.measure.data import
...``) and keeps only its own run (arguments, the run, printing and writing its results).

* :mod:`.data`: the shared data folders, :func:`~.data.run` (a tool as a subprocess), cameras made
  exactly from real CamVid frames with ``vcprep simulate``, study datasets;
* :mod:`.stats`: statistics over seeds (mean ± std, paired differences, a study's cells);
* :mod:`.tables`: markdown tables and the bar plot of those;
* :mod:`.models`: the models of a study (pipeline speed against a pure training step,
  convergence, one seed's rows);
* :mod:`.camera_change`: the camera change alone, on the simulated cameras;
* :mod:`.vp_reference`, :mod:`.vp_sets`, :mod:`.vp_scoring`: road vanishing points: the baseline
  and the reference rule, the sets, and their scoring;
* :mod:`.studies`: crossval studies as the scripts run them (a study file, its run, stores shared
  between seeds, the CamVid step budget); :mod:`.as_shipped_figures`: the one-training-camera
  verdict's cells, headline and page (benchmarks/other_cameras/as_shipped.py);
* :mod:`.folds`: leave-one-out folds (their command line, a held-out camera from its frames only);
* :mod:`.report`: what a result JSON records about its run, writing it, and where it goes
  (:func:`~.report.results_dir`: ``results/`` beside the script);
* :mod:`.page`: the results page's sections and the README's headline (benchmarks/results_page.py).

The scripts run as files (``.venv/bin/python benchmarks/<question>/<name>.py``); each puts the
repository first on ``sys.path`` with one line, so this package imports as ``benchmarks.measure``.
"""
