PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench wheel clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV) || python3 -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet -e '.[test,render]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/warerover run layouts/paper_homogeneous.yaml --seed 1 --executor physics --out runs/demo \
		--video videos/demo.mp4

test: $(STAMP)
	$(BIN)/python -m pytest -n auto --dist loadfile

lint: $(STAMP)
	$(BIN)/ruff check warerover_phys tests tools

bench: $(STAMP)
	$(BIN)/python tools/bench_loop.py

wheel: $(STAMP)
	bash tools/check_wheel.sh $(BIN)/python

clean:
	rm -rf $(VENV) runs .pytest_cache dist build
