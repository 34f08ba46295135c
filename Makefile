# Two commands do everything on a fresh machine:
#   make demo   - create .venv, install, warp the shipped example frames, write a figure, segment them
#                 with the shipped road model and score it on the KITTI frame (never trained on)
#   make test   - create .venv, install, run the test suite
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
OUT    ?= out/demo
MODEL  ?= models/road-multicamera/road.pt

.PHONY: install test demo bench clean fuzz docs

# torch==2.13.0 first: it resolves to the local CPU build; the package's own range (torch>=2.1,<3)
# is then already satisfied, so pip never pulls a multi-GB CUDA build.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q torch==2.13.0
	$(PY) -m pip install -q -e '.[dev,deploy]'
	touch $(STAMP)

install: $(STAMP)

test: $(STAMP)
	$(PY) -m pytest

demo: $(STAMP)
	$(BIN)/vcprep warp --camera camvid --images examples/camvid/images --labels examples/camvid/labels \
		--label-format camvid --out $(OUT)/store --quiet
	$(BIN)/vcprep warp --camera examples/kitti/calib/um_000000.txt --images examples/kitti/image_2 \
		--labels examples/kitti/gt_image_2 --label-format kitti --out $(OUT)/store --quiet
	$(BIN)/vcprep store show $(OUT)/store
	$(BIN)/vcprep figure warp $(OUT)/store -o $(OUT)/warp.png
	# the shipped model reads frames as they are (a resize model): no --camera (a virtual-camera MODEL=... needs one)
	$(BIN)/vctrain predict $(MODEL) examples/kitti/image_2 --out $(OUT)/road-kitti --overlay --quiet
	$(BIN)/vctrain predict $(MODEL) examples/camvid/images --out $(OUT)/road-camvid --overlay --quiet
	$(BIN)/vctrain eval $(OUT)/road-kitti --labels examples/kitti/gt_image_2 --label-format kitti --quiet
	@echo "demo: open $(OUT)/warp.png (original | virtual camera; road green, ignore dark, real pixels outlined in yellow, red + = the road vanishing point)"
	@echo "demo: the shipped road model on the examples: $(OUT)/road-kitti/um_000000_overlay.png, $(OUT)/road-camvid/*_overlay.png (road in green)"

bench: $(STAMP)
	$(PY) benchmarks/speed/warp.py

# docs/results.md and the README's headline, generated from benchmarks/*/results/*.json (tests/test_docs.py checks them)
docs: $(STAMP)
	$(PY) benchmarks/results_page.py

clean:
	rm -rf $(VENV) out *.egg-info

# property-based fuzzing of the readers: >= 10^4 examples each (the default test run uses 60)
fuzz: $(STAMP)
	HYPOTHESIS_PROFILE=fuzz $(PY) -m pytest tests/test_fuzz_readers.py -q
