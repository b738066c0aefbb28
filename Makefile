# econmotor — two commands on a fresh clone: `make demo` and `make test`.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.econmotor-installed
export OMP_NUM_THREADS ?= 1
export MKL_NUM_THREADS ?= 1

.PHONY: demo test venv holosoma bench-smoke lint clean mutation

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet torch==2.13.0
	$(PY) -m pip install --quiet -e '.[dev,mjx]'
	# the robot cards' MJCF (econmotor/robots) and the shipped walkers' ONNX: Holosoma's files only (its code needs numpy<2)
	$(PY) -m pip install --quiet --no-deps holosoma==0.0.3 holosoma-inference==0.1.3
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/econmotor demo

HVENV := .venv-holosoma
HPY := $(HVENV)/bin/python
HSTAMP := $(HVENV)/.econmotor-installed

# Holosoma's isolated interpreter (numpy<2); cached by $(HSTAMP). Order: torch, holosoma, mujoco.
$(HSTAMP): requirements-holosoma.txt pyproject.toml
	test -x $(HPY) || $(PYTHON) -m venv $(HVENV)
	$(HPY) -m pip install -qq --upgrade pip
	$(HPY) -m pip install -qq $$(grep -E '^torch==' requirements-holosoma.txt)
	$(HPY) -m pip install -qq $$(grep -E '^holosoma' requirements-holosoma.txt)
	$(HPY) -m pip install -qq -r requirements-holosoma.txt
	$(HPY) -m pip freeze --exclude-editable > $(HVENV)/constraints.txt
	$(HPY) -m pip install -qq -e . -c $(HVENV)/constraints.txt
	touch $(HSTAMP)

holosoma: $(HSTAMP)

# one pytest worker per core (pytest-xdist), a test file kept on one worker (its module fixtures built once);
# the 15 slowest tests are listed at the end, where the suite's time goes
TEST_WORKERS ?= auto
test: $(STAMP) $(HSTAMP)
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile --durations=15

# every benchmark at its smallest sizes, the MJX / Holosoma-training ones included (tens of minutes on a CPU)
bench-smoke: $(STAMP) $(HSTAMP)
	ECONMOTOR_BENCHMARKS=all $(PY) -m pytest -q tests/integration/test_benchmarks.py

lint: $(STAMP)
	$(PY) -m ruff check src tests

# Mutation testing (mutmut, [tool.mutmut] in pyproject.toml) of the modules that decide and price, against
# their fast unit tests; results are cached in mutants/ (a rerun tests only what changed). docs/mutation.md
mutation: $(STAMP)
	env -u PYTHONPATH nice -n 10 $(VENV)/bin/mutmut run --max-children 2
	$(PY) scripts/mutation_score.py

clean:
	rm -rf $(VENV) .econmotor runs .pytest_cache mutants
