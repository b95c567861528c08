# LumenLink: every target bootstraps a local .venv on first use (quick when it is already there).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-dev
BENCH_STAMP := $(VENV)/.installed-bench

.PHONY: demo serve test lint typecheck bench clean postgres

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $@

$(BENCH_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[dev,bench]'
	touch $@

demo: $(STAMP)
	$(BIN)/lumenlink demo

serve: $(STAMP)
	$(BIN)/lumenlink serve

lint: $(STAMP)
	$(BIN)/ruff check .

typecheck: $(STAMP)
	$(BIN)/mypy

test: $(STAMP) postgres lint typecheck
	$(BIN)/python -m pytest -q

# A PostgreSQL server for tests/service/test_replicas.py (it starts its own throw-away cluster in a temp dir):
# Debian's `postgresql` package, installed when no server is there and we may install it (root, apt-get).
postgres:
	@if ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1; then \
		:; \
	elif [ "$$(id -u)" != 0 ]; then \
		echo "postgres: no PostgreSQL server installed and not root: not installing Debian's postgresql" \
		     "package (apt-get needs root); tests/service/test_replicas.py is skipped"; \
	elif ! command -v apt-get >/dev/null 2>&1; then \
		echo "postgres: no PostgreSQL server installed and no apt-get to install it with:" \
		     "tests/service/test_replicas.py is skipped"; \
	else \
		echo "postgres: installing Debian's postgresql package (for tests/service/test_replicas.py)"; \
		{ apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends \
		    postgresql; } || echo "postgres: installing postgresql failed: tests/service/test_replicas.py is skipped"; \
	fi

bench: $(BENCH_STAMP)
	$(BIN)/lumenlink bench

clean:
	rm -rf $(VENV) var demo-output .pytest_cache
