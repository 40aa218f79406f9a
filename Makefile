PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench wheel clean docs

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

# The documentation site (mkdocs.yml): broken links, anchors and pages fail the build.
DOCS_STAMP := $(VENV)/.docs-installed
$(DOCS_STAMP): $(STAMP) pyproject.toml
	$(BIN)/python -m pip install --quiet -e '.[test,render,docs]'
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

wheel: $(STAMP)
	bash tools/check_wheel.sh $(BIN)/python

clean:
	rm -rf $(VENV) runs .pytest_cache dist build site
