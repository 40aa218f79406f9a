PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-slow test-all test-cov lint lacam3 bench wheel clean docs

$(BIN)/python:
	$(PYTHON) -m venv $(VENV) || python3 -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(STAMP): $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet -e '.[test,render]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/warerover run layouts/paper_homogeneous.yaml --seed 1 --executor physics --out runs/demo \
		--video videos/demo.mp4

# The default set (pyproject's addopts leave the slow tests out): the first signal, in minutes.
PYTEST_DEFAULT = $(BIN)/python -m pytest -n auto --dist loadfile
# The slow set alone (-m slow replaces the default "not slow"); worksteal spreads the many
# slow cases of one file (the determinism matrix) over the workers. Its cases are long
# (whole episodes, sweeps, a wheel install): a 30-minute hang guard instead of pyproject's
# 5 minutes, which five of them overran on a loaded two-core machine (load ~20).
PYTEST_SLOW = $(BIN)/python -m pytest -n auto --dist worksteal -m slow --timeout=1800

# TEST_ARGS: more pytest options for make test (tools/test_time.py passes --junitxml).
TEST_ARGS ?=
test: $(STAMP)
	$(PYTEST_DEFAULT) $(TEST_ARGS)

test-slow: $(STAMP)
	$(PYTEST_SLOW)

# Everything CI runs (.ci/run, with CI=true: derandomized hypothesis, a skip fails):
# lint first (seconds), the reference lacam3 binary a test reads, the default and the slow
# set under line coverage (test-cov), then the wheel on its own and the documentation site
# (mkdocs build --strict).
test-all: lint lacam3 test-cov wheel docs

# Both sets with pytest-cov (coverage of the package's lines run in the pytest processes;
# the CLI run as a subprocess and Ray's workers are not counted): build/coverage.txt.
COV_ARGS = --cov=warerover_phys --cov-append --cov-report=
test-cov: $(STAMP)
	@rm -f .coverage .coverage.*
	@mkdir -p build
	rc=0; $(PYTEST_DEFAULT) $(COV_ARGS) || rc=$$?; $(PYTEST_SLOW) $(COV_ARGS) || rc=$$?; \
	$(BIN)/python -m coverage report --precision=1 > build/coverage.txt; \
	echo "line coverage (default + slow set): $$(tail -1 build/coverage.txt)"; exit $$rc

# LaCAM3 (C++, ../shared/reference/lacam3) built into build/lacam3/main (cmake and g++).
LACAM3_SRC ?= ../shared/reference/lacam3
lacam3: build/lacam3/main

build/lacam3/main:
	@mkdir -p build
	@echo "building lacam3 from $(LACAM3_SRC) into build/lacam3 (log: build/lacam3.log)"
	@(cmake -S $(LACAM3_SRC) -B build/lacam3 -DCMAKE_BUILD_TYPE=Release \
		&& $(MAKE) -C build/lacam3 -j2) > build/lacam3.log 2>&1 \
		|| { tail -20 build/lacam3.log; exit 1; }

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
