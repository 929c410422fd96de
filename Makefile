# Two commands do all the set-up on a fresh Debian machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.hearth-installed

.PHONY: demo test install models bench lowest-deps clean

$(STAMP): pyproject.toml constraints.txt scripts/sysdeps.sh
	@test -x $(PY) || $(PYTHON) -m venv $(VENV) || { \
	  echo "make: could not create $(VENV); on Debian run: apt-get install -y python3-venv" >&2; exit 1; }
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -c constraints.txt -e '.[dev,btcpp,ros]'
	scripts/sysdeps.sh $(VENV)
	$(PY) -c "import open3d, py_trees, cv2, sklearn, lxml, transitions, joblib, zmq, behaviortreepy, btview"
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

# The oldest versions pyproject.toml allows, in a fresh venv: every module imports and the CLI
# runs (downloads ~250 MB of old wheels; not part of `make test`).
lowest-deps:
	scripts/lowest-deps.sh

clean:
	rm -rf $(VENV) build *.egg-info runs out
