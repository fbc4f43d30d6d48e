# unseen: every install step lives here.  `make demo` and `make test` set up what they need.
SHELL := /bin/bash
VENV  := .venv
PY    := $(VENV)/bin/python
STAMP := $(VENV)/.installed
# Debian libraries the wheels need: libusb for Open3D, Mesa EGL/OSMesa for headless MuJoCo rendering.
APT_PKGS := libusb-1.0-0 libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6
export MUJOCO_GL ?= egl
export PYOPENGL_PLATFORM ?= egl

.PHONY: install sysdeps test test-slow demo bench lint clean

install: $(STAMP)

$(STAMP): pyproject.toml
	@$(MAKE) --no-print-directory sysdeps
	@test -x $(PY) || python3 -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	@touch $(STAMP)

sysdeps:
	@if command -v dpkg >/dev/null 2>&1; then \
	  missing=""; for p in $(APT_PKGS); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	  if [ -n "$$missing" ]; then \
	    if [ "$$(id -u)" = 0 ]; then \
	      echo "installing system packages:$$missing"; \
	      apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing >/dev/null; \
	    else \
	      echo "missing system packages:$$missing"; \
	      echo "run: sudo apt-get install -y$$missing"; exit 1; \
	    fi; \
	  fi; \
	fi

test: install
	$(PY) -m pytest -q -n 2 --dist loadfile
	out=$$(mktemp -d) && $(VENV)/bin/unseen eval regression --out $$out


test-slow: install
	$(PY) -m pytest -q -m slow

demo: install
	$(VENV)/bin/unseen demo --out demo_out

bench: install
	$(PY) -m pip install --quiet 'compas-cra==0.8.0' || echo "compas-cra not installed: its column stays empty"
	$(VENV)/bin/unseen bench --out bench_out

lint: install
	$(VENV)/bin/ruff check .

clean:
	rm -rf $(VENV) demo_out bench_out *.egg-info .pytest_cache .ruff_cache
