# Two commands do all the set-up on a fresh Debian machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.hearth-installed

.PHONY: demo test install models bench clean

$(STAMP): pyproject.toml scripts/sysdeps.sh
	@test -x $(PY) || $(PYTHON) -m venv $(VENV) || { \
	  echo "make: could not create $(VENV); on Debian run: apt-get install -y python3-venv" >&2; exit 1; }
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev,ros]'
	scripts/sysdeps.sh $(VENV)
	$(PY) -c "import open3d, py_trees, cv2, sklearn, lxml, filterpy, transitions"
	@touch $(STAMP)

install: $(STAMP)

# The knob reader and the segmentation forest are trained once per machine from renderings of
# the demo home (a few minutes) and cached in $$HEARTH_MODEL_DIR (default ~/.cache/hearth);
# when they are current this takes a second or two.
models: $(STAMP)
	$(VENV)/bin/hearth train all

demo: models
	$(VENV)/bin/hearth demo

test: models
	$(PY) -m pytest -q

bench: $(STAMP)
	$(VENV)/bin/hearth bench all --json

clean:
	rm -rf $(VENV) build *.egg-info runs out
