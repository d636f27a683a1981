# VPL GI — set-up, demo, tests and packaging.
#
# Blender versions (bpy, Blender as a Python module), one venv each. BLENDER=4.5 (4.5 LTS) is
# the development default; `make test BLENDER=5.3` runs another, `make test-all` (CI) every one.
BLENDER ?= 4.5
BLENDERS := 4.5 5.3 4.2

PYTHON_VERSION_4.2 := 3.11
PYTHON_VERSION_4.5 := 3.11
PYTHON_VERSION_5.3 := 3.13
VENV_4.2 := .venv-4.2
VENV_4.5 := .venv
VENV_5.3 := .venv-5.3
REQUIREMENTS_4.2 := requirements-4.2.txt
REQUIREMENTS_4.5 := requirements-dev.txt
REQUIREMENTS_5.3 := requirements-5.3.txt
# What each version's suite runs (empty: the whole suite). 4.2 LTS, the oldest supported:
# everything that runs inside Blender (extension install, engine, export, CLI, renders against
# Cycles) and the stability suite (against its Cycles); the Blender-free core tests would run
# as on 4.5 (same Python, numpy, scipy, moderngl), so they run on 4.5 and 5.3 only.
TESTS_4.2 := tests/blender tests/stability
TESTS_4.5 :=
TESTS_5.3 :=
# A suite that runs longer is stopped (each should take well under 20 minutes on 2 cores).
SUITE_TIMEOUT ?= 25m

VENV := $(VENV_$(BLENDER))
ifeq ($(VENV),)
$(error unknown BLENDER=$(BLENDER): use one of $(BLENDERS))
endif
PYTHON_VERSION := $(PYTHON_VERSION_$(BLENDER))
REQUIREMENTS := $(REQUIREMENTS_$(BLENDER))
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
# PYTHON=/path/to/pythonX.Y picks the interpreter; otherwise tools/find_python.sh looks on PATH
# and in pyenv's versions.
PYTHON ?=

.PHONY: demo test test-all suite venv lint extension scenes clean

$(STAMP): $(REQUIREMENTS)
	@python=$$(PYTHON_$(subst .,_,$(PYTHON_VERSION))="$(PYTHON)" \
		tools/find_python.sh $(PYTHON_VERSION)) || \
		{ echo "error: Blender $(BLENDER) (bpy) needs Python $(PYTHON_VERSION)"; exit 1; }; \
	echo "Blender $(BLENDER): creating $(VENV) with $$python"; \
	"$$python" -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r $(REQUIREMENTS)
	touch $(STAMP)

## Create the venv of BLENDER (default 4.5) with its pinned requirements.
venv: $(STAMP)

## Render the default sample scene (the Cornell box) and say where the image went.
demo: $(STAMP)
	$(PY) -m addon render sample_scenes/cornell_box.blend -o renders/cornell_box.png

## Lint, then run BLENDER's suite (default 4.5: the whole suite).
test: lint suite

## The suite of BLENDER alone, timed.
suite: $(STAMP)
	@echo "== Blender $(BLENDER): $$($(PY) -c 'import importlib.metadata as m, sys; \
		print("bpy", m.version("bpy"), "on Python", sys.version.split()[0])')," \
		"tests: $(or $(TESTS_$(BLENDER)),all)"
	@start=$$(date +%s); status=0; \
	timeout $(SUITE_TIMEOUT) $(PY) -m pytest $(TESTS_$(BLENDER)) || status=$$?; \
	seconds=$$(( $$(date +%s) - start )); \
	if [ $$status -eq 124 ]; then echo "Blender $(BLENDER): stopped after $(SUITE_TIMEOUT)"; fi; \
	echo "== Blender $(BLENDER): suite $$([ $$status -eq 0 ] && echo passed || echo FAILED)" \
		"in $$((seconds / 60)) min $$((seconds % 60)) s"; \
	exit $$status

## Lint, then every supported Blender's suite one after another (what CI runs); fails if any
## fails, after running them all, and prints each one's time.
test-all: lint
	@for v in $(BLENDERS); do $(MAKE) --no-print-directory venv BLENDER=$$v || exit 1; done
	@status=0; summary=""; \
	for v in $(BLENDERS); do \
		start=$$(date +%s); \
		if $(MAKE) --no-print-directory suite BLENDER=$$v; then result=passed; \
		else result=FAILED; status=1; fi; \
		seconds=$$(( $$(date +%s) - start )); \
		summary="$$summary  Blender $$v: $$result in $$((seconds / 60)) min $$((seconds % 60)) s\n"; \
	done; \
	printf "\nSuites per Blender version (load average now: %s):\n$$summary" \
		"$$(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null)"; \
	exit $$status

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
