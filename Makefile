# The two set-up commands of the README: `make run` and `make test`.
# Each creates the virtual environment it needs and installs into it only
# what is missing, so a second run starts at once.

PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: run test bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

run: $(STAMP)
	$(VENV)/bin/freecal serve --data-dir data

test: $(STAMP)
	@bash scripts/ensure-system-packages.sh
	$(PY) -m pytest

bench: $(STAMP)
	$(PY) -m benchmarks $(NAME)

clean:
	rm -rf $(VENV)
