# The README's commands. Each one sets up .venv first when needed.
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.usdcrowd-installed

.PHONY: setup demo test test-fast bench schemas clean

$(STAMP): pyproject.toml tools/setup.sh
	bash tools/setup.sh
	touch $(STAMP)

setup: $(STAMP)

## The main job: a small scene end to end (outputs in out/demo).
demo: $(STAMP)
	$(VENV)/bin/usdcrowd demo -o out/demo

## The tests, all of them: the slow ones read our MOT files with motmetrics
## (in its own small venv, it needs numpy < 2), import our shots in Blender
## (the bpy wheel in its own venv) and start a local Ray cluster. They run
## in one worker per CPU (pytest-xdist), each test file on one worker so that
## its fixtures are made once; `.venv/bin/python -m pytest` runs them in one.
test: $(STAMP)
	$(PY) -m pytest -q -n logical --dist loadscope

## The tests without the slow ones, while developing.
test-fast: $(STAMP)
	$(PY) -m pytest -q -n logical --dist loadscope -m "not slow"

## The benchmarks install what they compare against (the bench extra: JuPedSim).
bench: $(STAMP)
	$(PY) -m pip install -q -e ".[bench]"
	$(PY) tools/bench.py

schemas: $(STAMP)
	$(PY) tools/regen_schemas.py

clean:
	rm -rf out build dist *.egg-info
