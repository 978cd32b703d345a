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
	$(BIN)/gait-tuner trajectory --gait tlipfm --out runs/quickstart/tlipfm
	$(BIN)/gait-tuner trajectory --gait eros --params eros-x16-with --out runs/quickstart/eros
	$(BIN)/gait-tuner trajectory --gait cosine --out runs/quickstart/cosine

test: $(STAMP)
	$(BIN)/python -m pytest -q

clean:
	rm -rf $(VENV) runs
