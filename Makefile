# The two set-up commands of the README: `make run` and `make test`.
# Each creates the virtual environment it needs and installs into it only
# what is missing, so a second run starts at once.

PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: run test test-fast lint bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

# The compiled kernels into numba's on-disk cache (about 30 s once; calib_core/warm_up.py),
# again whenever the code changes, so that the first photo set or calibration does not wait.
KERNELS := $(VENV)/.kernels
$(KERNELS): $(STAMP) $(shell find calib_core -name '*.py')
	$(PY) -m calib_core.warm_up
	touch $(KERNELS)

run: $(KERNELS)
	$(VENV)/bin/freecal serve --data-dir data

test: $(STAMP) lint $(KERNELS)
	@bash scripts/ensure-system-packages.sh
	@bash scripts/ensure-mrcal.sh >/dev/null
	# the science's tests on both cores; the service's and the page's one at a time (they start servers
	# and time a browser's walk); both always run, and the target fails if either did
	$(PY) -m pytest -n 2 tests/core; core=$$?; $(PY) -m pytest tests/service tests/browser && exit $$core

# The quick loop while editing: the science's tests under 5 s each (no server, no browser), on both cores.
test-fast: $(STAMP)
	$(PY) -m pytest -q -n 2 -m "not slow" tests/core

lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/mypy

bench: $(STAMP)
	$(PY) -m benchmarks $(NAME)

clean:
	rm -rf $(VENV)
