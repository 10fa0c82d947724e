# Two entry points for a fresh machine: `make run` and `make test`. Each sets itself up.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
MUJOCO_GL ?= egl
export MUJOCO_GL

.PHONY: setup run test lint clean

$(BIN)/.installed: pyproject.toml scripts/install_system_deps.sh
	bash scripts/install_system_deps.sh
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e ".[test]"
	touch $@

setup: $(BIN)/.installed

# Until the `imitate run` pipeline lands, the main job renders the testbed scene headless.
run: setup
	$(BIN)/python scripts/render_ci_video.py --out runs/latest/video.mp4 --seconds 4

test: setup lint
	$(BIN)/python -m pytest
	$(BIN)/python scripts/render_ci_video.py --out runs/ci/video.mp4 --width 160 --height 120 --check

lint: setup
	$(BIN)/ruff check .

clean:
	rm -rf $(VENV) runs build *.egg-info
