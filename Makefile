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

# the default run on two worker processes (pytest-xdist): both cores are busy throughout, so a
# test that waits for a window in wall time fails here (tests/run_loaded.py loads a machine by hand)
# (the sources byte-compiled first: where PYTHONDONTWRITEBYTECODE is set, every process the tests
# start would compile them again; a worker that runs out of tests takes the other's waiting ones,
# so neither idles while the other finishes a long tail)
test: $(STAMP)
	$(BIN)/python -m compileall -q tuner gaits > /dev/null
	$(BIN)/python -m pytest -q -n 2 --dist worksteal

clean:
	rm -rf $(VENV) runs
