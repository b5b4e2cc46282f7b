# The two commands the README promises: `make demo` and `make test`.
# Each creates .venv on first use (needs only python3) and installs what it needs.
PYTHON ?= python3
# test processes beside each other: 4 on a 2-core box, because most end-to-end tests wait
# on servers and simulated time (one run, loaded box: 2m47 with 4, 3m19 with 2); tests
# marked `timing` run alone afterwards
TEST_WORKERS ?= 4
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test lint typecheck bench soak clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev,plot]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/stiction-gateway demo

test: $(STAMP)
	$(BIN)/ruff check stiction gateway plcsim tests bench
	$(BIN)/mypy stiction gateway plcsim
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile -m "not timing"
	$(BIN)/python -m pytest -q -m timing

lint: $(STAMP)
	$(BIN)/ruff check stiction gateway plcsim tests bench

typecheck: $(STAMP)
	$(BIN)/mypy stiction gateway plcsim

bench: $(STAMP)
	$(BIN)/python -m bench

soak: $(STAMP)
	$(BIN)/python -m bench.soak

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .mypy_cache .ruff_cache
