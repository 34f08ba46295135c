"""Shared measuring code of the benchmarks, one module per topic; every ``benchmarks/<name>.py``
script imports what it needs from these and keeps only its own run (arguments, the run, printing
and writing its results).

* :mod:`measure.data`: the shared data folders, :func:`~measure.data.run` (a tool as a
  subprocess), cameras made exactly from real CamVid frames with ``vcprep simulate``, study datasets;
* :mod:`measure.stats`: statistics over seeds (mean ± std, paired differences, a study's cells);
* :mod:`measure.tables`: markdown tables and the bar plot of those;
* :mod:`measure.models`: the models of a study (pipeline speed against a pure training step,
  convergence, one seed's rows);
* :mod:`measure.camera_change`: the camera change alone, on the simulated cameras;
* :mod:`measure.vp_reference`, :mod:`measure.vp_sets`, :mod:`measure.vp_scoring`: road vanishing
  points: the baseline and the reference rule, the sets, and their scoring;
* :mod:`measure.report`: what a result JSON records about its run, and writing it.

The scripts run as files (``.venv/bin/python benchmarks/<name>.py``): Python puts a script's own
folder first on ``sys.path``, so this package imports as ``measure``; ``vcprep`` and ``vctrain``
come from the editable install (``make install``).
"""
