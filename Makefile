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
	$(PY) -m pip install -q -c constraints.txt -e '.[dev,btcpp,ros,ray,mujoco]'
	scripts/sysdeps.sh $(VENV)
	$(PY) -c "import open3d, py_trees, cv2, sklearn, lxml, transitions, joblib, zmq, behaviortreepy, btview, ray, mujoco"
	@touch $(STAMP)

install: $(STAMP)

# The perception models of a home: the knob reader, trained for that home from renderings of
# its own knobs, and the segmentation forest, trained once and shared by every home; cached in
# $$HEARTH_MODEL_DIR (default ~/.cache/hearth), one knob model per home. `make models` trains
# them for the demo home, `make models WORLD=my_home.xml` for yours (README: "Your own home");
# when they are current this takes a second or two.
WORLD ?= data/demo_home/world.xml

models: $(STAMP)
	$(VENV)/bin/hearth train all --world $(WORLD)

demo: models
	$(VENV)/bin/hearth demo

# Chromium for the monitor page's browser test (installed when root; otherwise the command is
# printed and that test is skipped, saying why).
test: models
	scripts/sysdeps.sh --browser $(VENV)
	$(PY) -m pytest -q

bench: $(STAMP)
	$(VENV)/bin/hearth bench all --json

# The oldest versions pyproject.toml allows, in a fresh venv: every module imports and the CLI
# runs (downloads ~250 MB of old wheels; not part of `make test`).
lowest-deps:
	scripts/lowest-deps.sh

clean:
	rm -rf $(VENV) build *.egg-info runs out
