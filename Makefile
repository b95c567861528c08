# LumenLink: every target bootstraps a local .venv on first use (quick when it is already there).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-dev
BENCH_STAMP := $(VENV)/.installed-bench
# the browser assets the service serves itself (three.js, Swagger UI, ReDoc): npm packages pinned by service/web's lockfile
WEB    := service/web
WEB_STAMP := $(WEB)/node_modules/.installed

.PHONY: demo demo-guide serve test lint typecheck bench clean postgres chromium freecad web

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
test: $(STAMP) $(WEB_STAMP) postgres chromium freecad lint typecheck
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder

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

# Chromium for the browser tests (tests/e2e/test_pages.py drives it with Playwright): Debian's `chromium` package,
# installed when /usr/bin/chromium is missing and we may install it (root, apt-get); Playwright's own browser
# download is not used.
chromium:
	@if [ -x /usr/bin/chromium ]; then \
		:; \
	elif [ "$$(id -u)" != 0 ]; then \
		echo "chromium: /usr/bin/chromium missing and not root: not installing Debian's chromium package" \
		     "(apt-get needs root); tests/e2e/test_pages.py is skipped"; \
	elif ! command -v apt-get >/dev/null 2>&1; then \
		echo "chromium: /usr/bin/chromium missing and no apt-get to install it with: tests/e2e/test_pages.py is skipped"; \
	else \
		echo "chromium: installing Debian's chromium package (for tests/e2e/test_pages.py)"; \
		{ apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends \
		    chromium; } || echo "chromium: installing chromium failed: tests/e2e/test_pages.py is skipped"; \
	fi

# FreeCAD for tests/cad_adapter/test_freecad*.py (a real CAD system: `lumenlink push model.FCStd` runs its headless
# freecadcmd; the add-on's workbench runs in its GUI under Xvfb): Debian's `freecad` and `xvfb` packages, installed
# when missing and we may install them (root, apt-get).
freecad:
	@if { command -v freecadcmd || command -v FreeCADCmd; } >/dev/null 2>&1 && command -v xvfb-run >/dev/null 2>&1; then \
		:; \
	elif [ "$$(id -u)" != 0 ]; then \
		echo "freecad: freecadcmd or xvfb-run missing and not root: not installing Debian's freecad and xvfb" \
		     "packages (apt-get needs root); tests/cad_adapter/test_freecad*.py are skipped"; \
	elif ! command -v apt-get >/dev/null 2>&1; then \
		echo "freecad: freecadcmd or xvfb-run missing and no apt-get to install them: tests/cad_adapter/test_freecad*.py are skipped"; \
	else \
		echo "freecad: installing Debian's freecad and xvfb packages (for tests/cad_adapter/test_freecad*.py)"; \
		{ apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends \
		    freecad xvfb xauth; } || echo "freecad: installing freecad failed: tests/cad_adapter/test_freecad*.py are skipped"; \
	fi

bench: $(BENCH_STAMP)
	$(BIN)/lumenlink bench

clean:
	rm -rf $(VENV) var demo-output .pytest_cache $(WEB)/node_modules
