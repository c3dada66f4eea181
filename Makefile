# Haze developer commands. Everything runs inside .venv, which the first command creates.

PYTHON311 ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
NEED_PY311 := Haze needs Python 3.11 (bpy 5.0.1 requires exactly 3.11): install it, e.g. with pyenv or \
your distribution's python3.11 package
IS_PY311 := -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))'

.DEFAULT_GOAL := help
.PHONY: help venv demo test lint bench extension clean distclean system-libs

help:
	@echo "make demo       render the main example to out/ (renderer, then through the Blender add-on)"
	@echo "make test       lint, then run the test suite"
	@echo "make lint       ruff check only"
	@echo "make bench      run the renderer benchmarks"
	@echo "make extension  build the Blender extension package"
	@echo "make clean      remove outputs and caches (keeps .venv)"
	@echo "make distclean  clean, and remove .venv too"

# An existing .venv is reused (pip install is quick when everything is satisfied); only a missing
# one is created, so python3.11 is needed on PATH only then.
$(STAMP): requirements.txt
	@if [ ! -x $(PY) ]; then \
		$(PYTHON311) $(IS_PY311) >/dev/null 2>&1 || { echo "$(NEED_PY311)"; exit 1; }; \
		echo "Creating $(VENV) with $(PYTHON311)"; \
		$(PYTHON311) -m venv $(VENV); \
	fi
	@$(PY) $(IS_PY311) || { echo "$(VENV) is not Python 3.11: run 'make distclean' first. $(NEED_PY311)"; exit 1; }
	$(PY) -m pip install --disable-pip-version-check -r requirements.txt
	@$(PY) -c "import bpy" >/dev/null 2>&1 || $(MAKE) --no-print-directory system-libs
	@touch $@

# bpy loads a few X11/GL libraries from the system. Installed here only when missing, and only
# where we may (root with apt-get); otherwise the message says what to install.
BPY_LIBS := libx11-6 libxrender1 libxi6 libxkbcommon0 libsm6 libgl1
system-libs:
	@if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
		echo "Installing the system libraries bpy loads: $(BPY_LIBS)"; \
		apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(BPY_LIBS); \
	else \
		echo "bpy cannot load its system libraries; install: $(BPY_LIBS)"; exit 1; \
	fi

venv: $(STAMP)

# The main example twice: straight through the renderer (also writing its scene folder), then
# built in Blender and rendered through the add-on the way a background script would.
demo: $(STAMP)
	$(PY) examples/demo.py
	$(PY) examples/blender_cornell.py

# Two test processes (pytest-xdist), whole files to each so a module's shared renders run
# once: most tests are one process, so serially one of two cores idles (CI: about 29 min
# serial). Kernels compile once across both (renderer.kernels.cache locks each function).
test: $(STAMP)
	$(VENV)/bin/ruff check .
	$(PY) -m pytest -q -n 2 --dist loadfile

lint: $(STAMP)
	$(VENV)/bin/ruff check .

bench: $(STAMP)
	$(PY) -m bench

extension: $(STAMP)
	$(PY) tools/build_extension.py

clean:
	rm -rf out dist build bench/cache .pytest_cache .ruff_cache
	find . -path ./$(VENV) -prune -o \( -name __pycache__ -o -name '*.nbi' -o -name '*.nbc' \) -print \
		| xargs -r rm -rf

distclean: clean
	rm -rf $(VENV)
