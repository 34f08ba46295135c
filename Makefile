# Two commands do everything on a fresh machine:
#   make demo   - create .venv, install, warp the shipped example frames, write a figure, segment them
#                 with the shipped road model and score it on the KITTI frame (never trained on)
#   make test   - create .venv, install, run the test suite
# From another directory (make -f path/to/Makefile demo) the repository's paths are taken from the
# Makefile's own folder (ROOT: empty at the repository root, so the commands there read as before);
# OUT stays in the directory make runs in.
HERE   := $(dir $(lastword $(MAKEFILE_LIST)))
ROOT   := $(if $(filter ./,$(HERE)),,$(abspath $(HERE))/)
PYTHON ?= python3
VENV   ?= $(ROOT).venv
PY     := $(VENV)/bin/python
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
OUT    ?= out/demo
MODEL  ?= $(ROOT)models/road-all/road.pt

.PHONY: install test demo bench clean fuzz docs

# torch==2.13.0 first: it resolves to the local CPU build; the package's own range (torch>=2.1,<3)
# is then already satisfied, so pip never pulls a multi-GB CUDA build.
$(STAMP): $(ROOT)pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q torch==2.13.0
	$(PY) -m pip install -q -e '$(if $(ROOT),$(ROOT:/=),.)[dev,deploy]'
	touch $(STAMP)

install: $(STAMP)

test: $(STAMP)
	$(if $(ROOT),cd $(ROOT) && )$(PY) -m pytest

demo: $(STAMP)
	$(BIN)/vcprep warp --camera camvid --images $(ROOT)examples/camvid/images --labels $(ROOT)examples/camvid/labels \
		--label-format camvid --out $(OUT)/store --quiet
	$(BIN)/vcprep warp --camera $(ROOT)examples/kitti/calib/um_000000.txt --images $(ROOT)examples/kitti/image_2 \
		--labels $(ROOT)examples/kitti/gt_image_2 --label-format kitti --out $(OUT)/store --quiet
	$(BIN)/vcprep store show $(OUT)/store
	$(BIN)/vcprep figure warp $(OUT)/store -o $(OUT)/warp.png
	# the shipped model reads frames as they are (a resize model): no --camera (a virtual-camera MODEL=... needs one)
	$(BIN)/vctrain predict $(MODEL) $(ROOT)examples/kitti/image_2 --out $(OUT)/road-kitti --overlay --quiet
	$(BIN)/vctrain predict $(MODEL) $(ROOT)examples/camvid/images --out $(OUT)/road-camvid --overlay --quiet
	$(BIN)/vctrain eval $(OUT)/road-kitti --labels $(ROOT)examples/kitti/gt_image_2 --label-format kitti --quiet
	@echo "demo: open $(OUT)/warp.png (original | virtual camera; road green, ignore dark, real pixels outlined in yellow, red + = the road vanishing point)"
	@echo "demo: the shipped road model on the examples: $(OUT)/road-kitti/um_000000_overlay.png, $(OUT)/road-camvid/*_overlay.png (road in green)"

bench: $(STAMP)
	$(PY) $(ROOT)benchmarks/speed/warp.py

# docs/results.md and the README's headline, generated from benchmarks/*/results/*.json (tests/test_docs.py checks them)
docs: $(STAMP)
	$(PY) $(ROOT)benchmarks/results_page.py

clean:
	rm -rf $(VENV) out $(ROOT)*.egg-info

# property-based fuzzing of the readers: >= 10^4 examples each (the default test run uses 60)
fuzz: $(STAMP)
	HYPOTHESIS_PROFILE=fuzz $(PY) -m pytest $(ROOT)tests/test_fuzz_readers.py -q
