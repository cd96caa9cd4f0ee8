# Two commands do all the set-up on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
NPM_STAMP := node_modules/.installed-stamp
BENCH_STAMP := $(VENV)/.bench-stamp
SUDO   := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

.PHONY: demo test install bench bench-all clean

# system packages: libusb for open3d, Node.js and npm for the viewer's JavaScript (when the machine has no node)
define apt_install
	$(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq $(1)
endef

# a virtual environment with the package and its test extras
$(STAMP): pyproject.toml
	@if ! ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then \
		echo "installing libusb-1.0-0 (needed by open3d)"; $(call apt_install,libusb-1.0-0); fi
	@if [ ! -f /usr/share/proj/egm96_15.gtx ]; then \
		echo "installing proj-data (the EGM96 geoid grid, for heights in a levelling datum)"; \
		$(call apt_install,proj-data); fi
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e ".[test]"
	@# byte-code once: a command then starts without compiling the package (also where PYTHONDONTWRITEBYTECODE is set)
	$(BIN)/python -m compileall -q twinreg cosco
	@touch $(STAMP)

# three.js for the viewer, the Khronos glTF validator, CesiumJS and playwright-core for the tests: exactly the locked
# versions from the npm registry (no browser download: the tests drive the system's Chromium)
$(NPM_STAMP): package.json package-lock.json
	@command -v npm >/dev/null || { echo "installing nodejs and npm"; $(call apt_install,nodejs npm); }
	npm ci --no-audit --no-fund --loglevel=error
	@touch $(NPM_STAMP)

# headless Chromium from Debian's packages, for the viewer's browser test
/usr/bin/chromium:
	@echo "installing chromium (the viewer's browser test)"
	$(call apt_install,chromium)

# CloudCompare from Debian's packages, for the test that opens twin.ply in it (headless)
/usr/bin/CloudCompare:
	@echo "installing cloudcompare (the twin.ply test opens it headless)"
	$(call apt_install,--no-install-recommends cloudcompare)

install: $(STAMP) $(NPM_STAMP)

demo: $(STAMP) $(NPM_STAMP)
	$(BIN)/twinreg demo

# the suite fails (instead of skipping) when ../shared/data is missing; plain `pytest` may skip, with a count.
# Two workers (pytest-xdist), a test file each at a time: a file's fixtures are built once, in one worker
test: $(STAMP) $(NPM_STAMP) /usr/bin/chromium /usr/bin/CloudCompare
	TWINREG_REQUIRE_SHARED_DATA=1 $(BIN)/python -m pytest -n 2 --dist loadfile

# the benches' baselines (scikit-learn's random forest)
$(BENCH_STAMP): $(STAMP)
	$(BIN)/python -m pip install -q -e ".[test,bench]"
	@touch $(BENCH_STAMP)

# the quick benches (minutes); the long ones are listed with their commands
bench: $(STAMP) $(NPM_STAMP) $(BENCH_STAMP)
	$(BIN)/python bench/run.py

# every bench, the long ones too (about an hour on 2 cores)
bench-all: $(STAMP) $(NPM_STAMP) $(BENCH_STAMP)
	$(BIN)/python bench/run.py --long

clean:
	rm -rf $(VENV) *.egg-info .pytest_cache node_modules
