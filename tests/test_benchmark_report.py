"""benchmarks/measure/report.py: every result JSON records its provenance (issue 79): the git commit, the
library versions, the machine, cores, Python and the date, without importing the libraries."""
from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

from benchmarks.measure import report

ROOT = Path(__file__).resolve().parents[1]
KEYS = {"commit", "dirty", "versions", "machine", "cores", "python", "date"}
LIBS = {"torch", "opencv", "numpy", "onnxruntime", "openvino"}


def test_written_result_records_its_provenance(tmp_path):
    data = {"headline": {"iou": 90.0}}
    path = report.write_json(tmp_path / "sub" / "r.json", data)
    written = json.loads(path.read_text())
    assert written["headline"] == {"iou": 90.0}
    prov = written["provenance"]
    assert set(prov) == KEYS and set(prov["versions"]) == LIBS
    assert prov["versions"]["numpy"] is not None  # installed with the package
    assert prov["cores"] == os.cpu_count() and prov["machine"] == report.machine()
    assert prov["date"] == report.today() and prov["python"].count(".") == 2
    assert prov["commit"] is None or (isinstance(prov["commit"], str) and isinstance(prov["dirty"], bool))
    assert "provenance" not in data  # the caller's dict is left as it is


def test_provenance_kept_and_lists_untouched(tmp_path):
    own = {"commit": "abc"}
    assert json.loads(report.write_json(tmp_path / "a.json", {"x": 1, "provenance": own}).read_text()) == {
        "x": 1, "provenance": own}
    assert json.loads(report.write_json(tmp_path / "b.json", [1, 2]).read_text()) == [1, 2]


def test_no_git_or_no_repository_gives_null(tmp_path, monkeypatch):
    assert report.git_commit(tmp_path) == {"commit": None, "dirty": None}  # not a repository
    monkeypatch.setenv("PATH", str(tmp_path))  # no git on the PATH
    assert report.git_commit(ROOT) == {"commit": None, "dirty": None}


def test_writing_a_result_imports_no_library(tmp_path):
    code = ("import sys, json; from benchmarks.measure.report import write_json; "
            f"write_json(__import__('pathlib').Path({str(tmp_path / 'r.json')!r}), {{'a': 1}}); "
            "print(json.dumps(sorted(m for m in ('torch', 'cv2', 'onnxruntime', 'openvino') if m in sys.modules)))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                         env={**os.environ, "PYTHONPATH": str(ROOT)}, check=True)
    assert json.loads(run.stdout) == []
    assert json.loads((tmp_path / "r.json").read_text())["provenance"]["versions"]["torch"] is not None


def test_results_page_shows_the_provenance(tmp_path):
    spec = importlib.util.spec_from_file_location("results_page", ROOT / "benchmarks" / "results_page.py")
    rp = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(rp)
    prov = {"commit": "abc1234", "dirty": True, "machine": "x86_64, 2 cores", "cores": 2, "python": "3.11.7",
            "date": "2026-12-06", "versions": {"torch": "2.13.0", "opencv": "5.1.0", "numpy": "2.4.6",
                                               "onnxruntime": None, "openvino": "2026.4.1"}}
    facts = dict(rp.run_facts(tmp_path / "x.json", {"headline": {"iou": 1.0}, "provenance": prov}))
    assert facts["date"] == "2026-12-06"
    assert facts["machine"] == ("x86_64, 2 cores; python 3.11.7; torch 2.13.0; opencv 5.1.0; numpy 2.4.6; "
                                "openvino 2026.4.1; commit abc1234 (uncommitted changes)")
    assert rp.recorded_versions({"provenance": prov}) == {"OpenCV": "5.1.0", "numpy": "2.4.6", "torch": "2.13.0"}
    assert "provenance" not in "\n".join(rp.renderer("x")({"iou": 1.0, "provenance": prov}))
