# The two commands the README promises: `make demo` and `make test`.
# Each creates .venv on first use (needs only python3) and installs what it needs.
PYTHON ?= python3
# test processes beside each other: 4 on a 2-core box, because most end-to-end tests wait
# on servers and simulated time (one run, loaded box: 2m47 with 4, 3m19 with 2); tests
# marked `timing` run alone afterwards
TEST_WORKERS ?= 4
VENV   := .venv
BIN     = $(VENV)/bin
STAMP   = $(VENV)/.installed
# the bench's extras on top (tep-studio for the development corpus: never make test's)
BENCH_STAMP = $(VENV)/.installed-bench
# the exact versions make test, make demo and the wheelhouse install (docs/install.md) use;
# `make lock` renews it from the newest releases, `make test-latest` tries them first
LOCK   := constraints.txt

.PHONY: demo test lint typecheck bench corpus soak clean lock test-latest

$(STAMP): pyproject.toml $(LOCK)
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --constraint $(LOCK) --upgrade pip
	$(BIN)/pip install --quiet --constraint $(LOCK) -e '.[dev,plot]'
	touch $(STAMP)

# options of `stiction-gateway demo`, e.g. make demo DEMO_ARGS="--duration 60"
DEMO_ARGS ?=

demo: $(STAMP)
	$(BIN)/stiction-gateway demo $(DEMO_ARGS)

test: $(STAMP)
	$(BIN)/ruff check stiction gateway plcsim lab tests bench
	$(BIN)/mypy stiction gateway plcsim lab
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile -m "not timing"
	$(BIN)/python -m pytest -q -m timing

lint: $(STAMP)
	$(BIN)/ruff check stiction gateway plcsim lab tests bench

typecheck: $(STAMP)
	$(BIN)/mypy stiction gateway plcsim lab

$(BENCH_STAMP): $(STAMP)
	$(BIN)/pip install --quiet --constraint $(LOCK) -e '.[dev,plot,bench]'
	touch $(BENCH_STAMP)

bench: $(BENCH_STAMP)
	$(BIN)/python -m bench

# the development corpus (lab/labels/corpus.py): builds what lab/.cache/corpus lacks, then
# prints its summary; the first build takes about an hour of one core
corpus: $(BENCH_STAMP)
	$(BIN)/python -m lab corpus

soak: $(STAMP)
	$(BIN)/python -m bench.field.soak

# the newest release of every dependency (no lock) in .venv-latest, then the whole suite:
# what `make lock` would bring in, before it is committed
test-latest:
	rm -rf .venv-latest
	$(PYTHON) -m venv .venv-latest
	.venv-latest/bin/pip install --quiet --upgrade pip
	.venv-latest/bin/pip install --quiet -e '.[dev,plot]'
	touch .venv-latest/.installed
	$(MAKE) test VENV=.venv-latest

# renew the lock: resolve pyproject's ranges afresh in a throw-away venv, pin what came
lock:
	rm -rf .venv-lock
	$(PYTHON) -m venv .venv-lock
	.venv-lock/bin/pip install --quiet --upgrade pip
	.venv-lock/bin/pip install --quiet '.[dev,plot,bench]'
	{ echo "# The exact versions a fresh install uses (make test, make demo, the wheelhouse)."; \
	  echo "# Renewed by 'make lock'; 'make test-latest' shows what the newest would break."; \
	  .venv-lock/bin/pip freeze --all --exclude stiction-gateway --exclude setuptools \
	    --exclude wheel; } > $(LOCK)
	rm -rf .venv-lock

clean:
	rm -rf $(VENV) .venv-latest .venv-lock build *.egg-info .pytest_cache .mypy_cache .ruff_cache
