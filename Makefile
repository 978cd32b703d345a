# One command sets everything up and runs the main job:   make run
# One command sets everything up and runs the tests:      make test
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: run test clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/gait-tuner tune studies/quickstart.yaml --workers 2
	$(BIN)/gait-tuner export studies/quickstart.yaml --out runs/quickstart/best.yaml
	$(BIN)/gait-tuner compare runs/quickstart/best.yaml --study studies/quickstart.yaml --out runs/quickstart/compare

# the default run, then the kill/resume and bad-input tests again with every core kept busy
# (tests/run_loaded.py): a test that waits for a window in wall time fails there
test: $(STAMP)
	$(BIN)/python -m pytest -q
	$(BIN)/python tests/run_loaded.py tests/test_storage.py tests/test_bad_input.py -p no:cacheprovider

clean:
	rm -rf $(VENV) runs
