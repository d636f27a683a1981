# VPL GI — set-up, demo, tests and packaging.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test lint extension scenes clean

$(STAMP): requirements-dev.txt
	@$(PYTHON) -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' || \
		{ echo "error: Python 3.11 is needed (bpy 4.5 is built for it); set PYTHON=..."; exit 1; }
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements-dev.txt
	touch $(STAMP)

## Render the default sample scene (the Cornell box) and say where the image went.
demo: $(STAMP)
	$(PY) -m addon render sample_scenes/cornell_box.blend -o renders/cornell_box.png

## Lint and run the whole test suite.
test: $(STAMP) lint
	$(PY) -m pytest

lint: $(STAMP)
	$(VENV)/bin/ruff check .

## Build dist/vpl_gi-<version>-<platform>.zip, one per platform, with Blender's extension tooling.
extension: $(STAMP)
	$(PY) tools/build_extension.py

## Rebuild the sample .blend files from code.
scenes: $(STAMP)
	$(PY) sample_scenes/build_scenes.py

clean:
	rm -rf dist wheels renders .pytest_cache .ruff_cache
