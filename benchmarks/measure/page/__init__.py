"""The results page (docs/results.md) and the README's headline, as benchmarks/results_page.py writes
them from benchmarks/*/results/*.json:

* :mod:`.format`: number formats and Markdown tables, deterministic;
* :mod:`.sections`: one renderer per benchmark JSON (``RENDER``);
* :mod:`.multi_camera`: the renderers of the multi-camera benchmarks;
* :mod:`.headline`: the README's headline table, and where each README figure comes from.
"""
