# hmdem: every target first runs the idempotent `setup`.
SHELL := /bin/bash
VENV := .venv
PY := $(VENV)/bin/python
SYS_PY := /usr/bin/python3
APT_PKGS := yade python3-yade python3-venv
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
STAMP := $(VENV)/.hmdem-installed

.PHONY: setup demo test validate bench bench-huang calibrate clean packing huang-packing

setup: $(STAMP)

$(STAMP): pyproject.toml
	@missing=""; for p in $(APT_PKGS); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  echo "[setup] apt-get install$$missing"; \
	  $(SUDO) apt-get update -q && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -q $$missing; \
	fi
	@[ -x $(PY) ] || $(SYS_PY) -m venv --system-site-packages $(VENV)
	$(PY) -m pip install -q --upgrade pip
	# --ignore-installed shadows Debian's old numpy/matplotlib from dist-packages inside the venv
	$(PY) -m pip install -q --ignore-installed 'numpy>=2' 'matplotlib>=3.8'
	$(PY) -m pip install -q -e '.[test]'
	$(PY) -c "import hmdem.yade_env as y; y.import_yade(); print('[setup] YADE importable')"
	@touch $(STAMP)

demo: setup
	$(PY) -m hmdem.hele_shaw

test: setup
	$(PY) -m pytest -q

validate: setup
	$(PY) -m pytest -q -m slow

bench: setup
	$(PY) benchmarks/run_benchmarks.py
	$(PY) benchmarks/scaling.py

# the four Huang cases at paper size, one after the other (hours: see BENCHMARKS.md)
bench-huang: setup
	$(PY) benchmarks/huang.py --out runs/bench

calibrate: setup
	$(PY) -m hmdem.calibrate biaxial
	$(PY) -m hmdem.calibrate darcy

packing: setup
	$(PY) -m hmdem.dem.packing --overwrite --out hmdem/data/lenormand_packing.npz

huang-packing: setup
	$(PY) -m hmdem.dem.compaction --overwrite --out hmdem/data/huang_packing.npz

clean:
	rm -rf $(VENV) runs
