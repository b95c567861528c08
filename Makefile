# LumenLink: every target bootstraps a local .venv on first use (quick when it is already there).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-dev
BENCH_STAMP := $(VENV)/.installed-bench
# the browser assets the service serves itself (three.js, Swagger UI, ReDoc): npm packages pinned by service/web's lockfile
WEB    := service/web
WEB_STAMP := $(WEB)/node_modules/.installed

.PHONY: demo demo-guide serve test lint typecheck bench clean system postgres chromium freecad web

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $@

$(BENCH_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[dev,bench]'
	touch $@

demo: $(STAMP) $(WEB_STAMP)
	$(BIN)/lumenlink demo

demo-guide: $(STAMP)
	$(BIN)/lumenlink demo-guide

serve: $(STAMP) $(WEB_STAMP)
	$(BIN)/lumenlink serve

# The pages' and the API docs' scripts, from the npm registry, exactly as package-lock.json pins them (integrity
# hashes); nothing is fetched at run time. Without npm the service still runs, its pages say what is missing.
$(WEB_STAMP): $(WEB)/package.json $(WEB)/package-lock.json
	@if command -v npm >/dev/null 2>&1; then \
		cd $(WEB) && npm ci --ignore-scripts --no-audit --no-fund --loglevel=error && touch node_modules/.installed; \
	else \
		echo "web: npm not found: the pages at / and the API docs at /docs have no scripts (install Node.js and npm)"; \
	fi

web: $(WEB_STAMP)

lint: $(STAMP)
	$(BIN)/ruff check .

typecheck: $(STAMP)
	$(BIN)/mypy

# pytest in TEST_WORKERS processes (pytest-xdist), a test file to each at a time (its module fixtures, a service or a
# cluster, are made once), longest first in the order tests/conftest.py gives; processes that need the same kernel
# compile it once (tracer.warmup.compiling)
TEST_WORKERS ?= 2
test: $(STAMP) $(WEB_STAMP) system lint typecheck
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder

# What some tests need from Debian, installed when missing and we may install it (root, apt-get), in one apt-get
# (a fresh machine pays one index update and one dpkg run for all of them); where we may not, those tests are skipped,
# saying why:
#   postgresql         a PostgreSQL server for tests/service/test_replicas.py (its own throw-away cluster)
#   chromium           the browser Playwright drives in tests/e2e/test_pages.py (no browser download of its own)
#   freecad xvfb xauth a real CAD system for tests/cad_adapter/test_freecad*.py (headless freecadcmd; its GUI under Xvfb)
system:
	@missing=""; \
	ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1 || missing="$$missing postgresql"; \
	[ -x /usr/bin/chromium ] || missing="$$missing chromium"; \
	{ command -v freecadcmd || command -v FreeCADCmd; } >/dev/null 2>&1 || missing="$$missing freecad"; \
	command -v xvfb-run >/dev/null 2>&1 || missing="$$missing xvfb xauth"; \
	if [ -z "$$missing" ]; then \
		:; \
	elif [ "$$(id -u)" != 0 ] || ! command -v apt-get >/dev/null 2>&1; then \
		echo "system: missing Debian packages:$$missing; not root or no apt-get: not installing them; the tests" \
		     "that need them are skipped, saying why"; \
	else \
		echo "system: installing Debian packages:$$missing"; \
		export DEBIAN_FRONTEND=noninteractive; \
		if apt-get update -q; then \
			apt-get install -y -q --no-install-recommends $$missing || \
			for p in $$missing; do apt-get install -y -q --no-install-recommends $$p || \
				echo "system: installing $$p failed: the tests that need it are skipped"; done; \
		else \
			echo "system: apt-get update failed: not installing$$missing; the tests that need them are skipped"; \
		fi; \
	fi

postgres chromium freecad: system

bench: $(BENCH_STAMP)
	$(BIN)/lumenlink bench

clean:
	rm -rf $(VENV) var demo-output .pytest_cache $(WEB)/node_modules
