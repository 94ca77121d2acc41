# The README's commands. Each one sets up .venv first when needed.
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.usdcrowd-installed

.PHONY: setup demo test test-all bench schemas clean

$(STAMP): pyproject.toml tools/setup.sh
	bash tools/setup.sh
	touch $(STAMP)

setup: $(STAMP)

## The main job: a small scene end to end (outputs in out/demo).
demo: $(STAMP)
	$(VENV)/bin/usdcrowd demo -o out/demo

## The tests (fast ones; `make test-all` adds the slow ones).
test: $(STAMP)
	$(PY) -m pytest -q -m "not slow"

test-all: $(STAMP)
	$(PY) -m pytest -q

bench: $(STAMP)
	$(PY) tools/bench.py

schemas: $(STAMP)
	$(PY) tools/regen_schemas.py

clean:
	rm -rf out build dist *.egg-info
