# Each public target sets up what it needs on a fresh machine: Debian GL libraries (as root),
# a .venv, torch==2.13.0 (CPU) and the package in editable mode, all through constraints.txt.
# demo and bench install the package with its viz extra; test and lint add dev and ray (ray
# alone is 30 s of a first demo's 15-minute budget). The stamps make a re-run cost nothing
# when pyproject.toml and constraints.txt are unchanged.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
DEV_STAMP := $(VENV)/.installed-dev
GL_STAMP := $(VENV)/.gl-ok
export MUJOCO_GL ?= egl
export PYOPENGL_PLATFORM ?= egl

.PHONY: demo test bench lint mypy-path setup setup-dev clean-venv

demo: setup
	$(VENV)/bin/beo-bench demo

test: setup-dev lint
	$(PY) -m pytest -n 2 --dist loadfile

bench: setup
	$(PY) benchmarks/run.py

lint: setup-dev
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .
	@$(MAKE) --no-print-directory mypy-path
	$(VENV)/bin/mypy

# mypy cannot follow package-dir (the editable install maps envs/, scenes/ and perception/ into
# beo_bench with an import hook), so it reads the package through a tree of relative symlinks:
# beo_bench's own entries and the three mapped folders side by side ([tool.mypy] mypy_path).
# Rebuilt on every lint, so that new modules are seen.
MYPY_PATH := $(VENV)/mypy-path
mypy-path:
	@rm -rf $(MYPY_PATH)
	@mkdir -p $(MYPY_PATH)/beo_bench
	@for p in beo_bench/* envs scenes perception; do \
	  case $$p in */__pycache__) continue;; esac; \
	  ln -s ../../../$$p $(MYPY_PATH)/beo_bench/; \
	done

setup: $(STAMP) $(GL_STAMP)

setup-dev: setup $(DEV_STAMP)

# Mesa's EGL (llvmpipe renders on the CPU) and OSMesa as the fallback; see docs/design.md "Scenes".
$(GL_STAMP):
	@mkdir -p $(VENV)
	@if ldconfig -p | grep -q 'libEGL.so.1' && ldconfig -p | grep -q 'libOpenGL.so.0' \
	    && ls /usr/lib/*/dri/swrast_dri.so >/dev/null 2>&1; then \
	  echo "GL libraries present"; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
	    libegl1 libegl-mesa0 libgl1-mesa-dri libopengl0 libosmesa6 >/dev/null; \
	else \
	  echo "Missing GL libraries: install libegl1 libegl-mesa0 libgl1-mesa-dri libopengl0 (or libosmesa6) as root." >&2; \
	  exit 1; \
	fi
	@touch $@

$(STAMP): pyproject.toml constraints.txt
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -c constraints.txt torch==2.13.0
	$(PY) -m pip install -q -c constraints.txt -e '.[viz]'
	@touch $@

$(DEV_STAMP): $(STAMP)
	$(PY) -m pip install -q -c constraints.txt -e '.[dev,viz,ray]'
	@touch $@

clean-venv:
	rm -rf $(VENV)
