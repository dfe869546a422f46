# gaitloop: `make run` sets up and runs the pipeline on the example subjects; `make test` sets up
# and runs the test suite. Both create the virtual environment when it is missing.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
export DVC_NO_ANALYTICS := 1
export MPLBACKEND := Agg
# Modules are byte-compiled when first imported, not at install: pip's compile of every installed
# module (~19 k files, torch and ray included) took a minute of the venv build, and the pipeline
# imports about a fifth of them. That needs bytecode to be written (a shell may forbid it).
unexport PYTHONDONTWRITEBYTECODE

.PHONY: run test docs lint bench videos clean-venv render-deps browser-deps

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet --no-compile -e '.[dev]'
	touch $(STAMP)

# Headless MuJoCo rendering for `scale` (sim/body/render.py) needs EGL (Mesa, in the base image) or
# OSMesa; Debian's libosmesa6 is installed only when neither library is present.
render-deps:
	@ldconfig -p | grep -q -e libEGL_mesa -e libOSMesa || \
		(apt-get update -qq && apt-get install -y -qq libosmesa6)

# The report test loads reports/index.html in a real browser (tests/pipeline/test_report.py): Debian's
# chromium is installed when it is missing, so the test runs everywhere, CI included.
browser-deps:
	@command -v chromium >/dev/null || \
		(apt-get update -qq && apt-get install -y -qq --no-install-recommends chromium >/dev/null)

# The pipeline up to the reports and the summary (every stage but `bench`, whose timings take
# minutes of their own: `make bench`), its stages sharing one local Ray head (python -m pipeline run).
run: $(STAMP) render-deps
	PATH="$(CURDIR)/$(BIN):$$PATH" $(BIN)/python -m pipeline run summary report

test: $(STAMP) render-deps browser-deps
	$(BIN)/ruff check .
	$(BIN)/python -m pytest

# The manual (docs/, mkdocs.yml) as a static site in build/docs/ (git-ignored); --strict: a broken link fails.
docs: $(STAMP)
	$(BIN)/mkdocs build --strict --site-dir build/docs

bench: $(STAMP)
	PATH="$(CURDIR)/$(BIN):$$PATH" $(BIN)/dvc repro bench

# One walk_10m video of the policy human per subject and condition (reports/<subject>/
# rollout_walk_10m_<condition>.mp4); about half a minute each, so not part of `make run`.
VIDEO_SUBJECTS ?= camargo opencap4
VIDEO_CONDITIONS ?= free pid adaptive
videos: $(STAMP) render-deps
	for s in $(VIDEO_SUBJECTS); do for c in $(VIDEO_CONDITIONS); do \
		$(BIN)/python -m pipeline render $$s $$c --scenario walk_10m || exit 1; done; done

clean-venv:
	rm -rf $(VENV)
