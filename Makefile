# Two entry points for a fresh machine: `make run` and `make test`. Each sets itself up.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
LOWEST := .venv-lowest
LEROBOT := .venv-lerobot
RUN ?= runs/latest
MUJOCO_GL ?= egl
export MUJOCO_GL

.PHONY: setup setup-test run test suite test-lowest test-lerobot lint clean

# System libraries, the virtual environment and the package with $(1) (extras, or nothing).
define install
	bash scripts/ci/install_system_deps.sh
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip uninstall --quiet --yes imitate 2>/dev/null || true  # the distribution's old name
	$(BIN)/pip install --quiet -e ".$(1)"
endef

# What `make run` needs, and the export extra: the README's examples export a dataset.
$(BIN)/.installed: pyproject.toml scripts/ci/install_system_deps.sh
	$(call install,[export])
	touch $@

# Plus the test-only dependencies (pytest, ruff and the cross-check libraries), in the same
# pip call on a fresh machine (each editable install builds the package once more).
$(BIN)/.installed-test: pyproject.toml scripts/ci/install_system_deps.sh
	$(call install,[test])
	touch $(BIN)/.installed $@

# numba compiles the kernels (the list in imitate/warmup.py) into its cache now, two
# processes at once, so that the first run loads them (again whenever a kernel's source changes).
KERNELS := $(shell grep -o '"imitate\.[a-z_.]*"' imitate/warmup.py | tr -d '"' | \
	sed 's|\.|/|g; s|$$|.py|')
$(BIN)/.compiled: $(BIN)/.installed $(KERNELS)
	$(BIN)/python -m imitate.warmup
	touch $@

# setup-test compiles once the test packages are installed (their stamp stands for .installed
# too): as two prerequisites, `make -j2` would install both into one venv at once.
setup: $(BIN)/.installed $(BIN)/.compiled
setup-test: $(BIN)/.installed-test
	@$(MAKE) -s --no-print-directory $(BIN)/.compiled

# The whole pipeline on the default settings: watch, learn, optimize, pour, figures, video.
run: setup
	$(BIN)/imitate run --out $(RUN)

# Two jobs side by side, each installing and compiling what it needs: the suite, and the
# lowest versions' check, which yields the processor to the suite (nice) and so runs where the
# suite leaves a core idle (pip, the warm-up, the suite's last test files). The system
# libraries first, once, so that the two jobs never run apt-get at the same time.
test:
	bash scripts/ci/install_system_deps.sh --test
	$(MAKE) -j2 suite test-lowest

suite: setup-test lint
	$(BIN)/python -m pytest -n auto --dist loadfile
	$(BIN)/python scripts/ci/render_ci_video.py --out runs/ci/video.mp4 --width 160 --height 120 --check

# ruff checks the project's own files only (pyproject.toml's [tool.ruff] include), not a
# user's scratch scripts in the clone.
lint: setup-test
	$(BIN)/ruff check .
	$(BIN)/python scripts/ci/typecheck.py

# The lowest versions pyproject.toml allows (every lower bound pinned, wheels only) on the env
# and scene tests and a whole quick run, whose task must succeed (check_outcome.py), at a lower
# priority (nice); numba's cache of them kept apart from .venv's and filled by the warm-up
# first (two processes at once, as `make setup` does). pip does not byte-compile there
# (--no-compile): two processes import from it, and compiling what they import costs less than
# compiling every file (even where PYTHONDONTWRITEBYTECODE keeps no .pyc; not so for .venv,
# whose packages a hundred processes of the suite import).
LOWEST_ENV := NUMBA_CACHE_DIR=$(LOWEST)/numba nice -n 10
$(LOWEST)/.installed: pyproject.toml scripts/ci/lowest_requirements.py scripts/ci/install_system_deps.sh
	bash scripts/ci/install_system_deps.sh
	rm -rf $(LOWEST)
	$(PYTHON) -m venv $(LOWEST)
	$(PYTHON) scripts/ci/lowest_requirements.py > $(LOWEST)/requirements.txt
	nice -n 10 $(LOWEST)/bin/pip install --quiet --no-compile --only-binary :all: -r $(LOWEST)/requirements.txt pytest
	$(LOWEST)/bin/pip install --quiet --no-compile --no-deps -e .
	touch $@

# Its output goes to a log, printed as one block when it ends (it runs beside the suite).
test-lowest: $(LOWEST)/.installed
	@echo "lowest versions: warm-up, env and scene tests, a quick run's outcome (output at the end)"
	@{ $(LOWEST_ENV) $(LOWEST)/bin/python -m imitate.warmup && \
	   $(LOWEST_ENV) $(LOWEST)/bin/python -m pytest -q -p no:cacheprovider \
		tests/test_env.py tests/test_scene.py && \
	   $(LOWEST_ENV) $(LOWEST)/bin/imitate run --quick --out runs/lowest && \
	   $(LOWEST)/bin/python scripts/ci/check_outcome.py runs/lowest; \
	 } > $(LOWEST)/test.log 2>&1; status=$$?; \
	 echo "== lowest versions ($(LOWEST)/test.log)"; cat $(LOWEST)/test.log; exit $$status

# LeRobot's own reader on an exported dataset, outside `make test`: LeRobot brings torch (about
# 4 min to install on two cores), in a virtual environment of its own; 0.4 reads the v3.0 format.
test-lerobot:
	bash scripts/ci/install_system_deps.sh
	$(PYTHON) -m venv $(LEROBOT)
	$(LEROBOT)/bin/pip install --quiet -e ".[export]" pytest "lerobot>=0.4,<0.5"
	$(LEROBOT)/bin/python -m pytest -q -p no:cacheprovider tests/test_export.py -k lerobot

clean:
	rm -rf $(VENV) $(LOWEST) $(LEROBOT) runs build *.egg-info
