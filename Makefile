# The two commands: `make run` (the GUI) and `make test` (the whole suite).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: venv run test test-other-cpu lint bench screenshots baselines mutate clean

venv: $(STAMP)

$(STAMP): pyproject.toml
	@bash scripts/ensure-system-deps.sh
	@$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 11), "livox-viz needs Python >= 3.11"'
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV) || { \
	  echo "error: '$(PYTHON) -m venv' failed: on Debian install python3-venv (apt-get install python3-venv)"; \
	  rm -rf $(VENV); exit 1; }
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	@# The compiled loops, once, where the install runs (about 30 s on 2 cores): the window's first datasheet scan
	@# is then ready at once, and the suite loads them instead of compiling them in its first tests.
	$(BIN)/livox-viz prepare
	@# mypy's caches for tests/test_static_platforms.py, made once here as the loops are: cold, the three platforms'
	@# checks were 19 s of a fresh clone's make test (2 s warm). Its findings are the test's to judge, not the install's.
	@for platform in linux win32 darwin; do \
	  $(BIN)/python -m mypy --platform $$platform --cache-dir .mypy_cache/$$platform --no-error-summary \
	    --show-error-codes > /dev/null 2>&1 & \
	done; wait
	@touch $(STAMP)

# Without a display the GUI renders its views into offscreen/ (one set, replaced each run), never screenshots/.
run: venv
	$(BIN)/livox-viz gui

# The suite's processes: the machine's cores, 2 to 4 (each holds its own numba, VTK and Xvfb: about 1 GB).
# `make test TEST_WORKERS=1` runs it in one process, as `.venv/bin/python -m pytest` does. The tests that start
# X servers share one worker (their xdist_group): servers of two workers raced for a display number.
TEST_WORKERS ?= $(shell $(PYTHON) -c 'import os; print(min(4, max(2, os.cpu_count() or 2)))')

# A worker that crashes (a segmentation fault, or the hang guard of tests/conftest.py ending a stuck test) ends the
# run with a failure: pytest-xdist's loadgroup scheduler, given a new worker in its place, handed it nothing, and the
# run waited for ever with every worker idle (how CI's run hung until its 90 minutes).
XDIST := -n $(TEST_WORKERS) --dist loadgroup --max-worker-restart=0

test: venv
	$(BIN)/python -m pytest $(XDIST)

# The model's numbers again as another CPU would compute them (another OpenBLAS kernel family, numba for a generic
# CPU): a test that holds only by this machine's rounding fails here, not on a user's machine. Only the tests marked
# `arithmetic` (tests/conftest.py): the window, messages and signals do not change with a CPU. CI runs it after
# `make test`.
test-other-cpu: venv
	$(BIN)/python scripts/other_cpu.py -q $(XDIST) -m arithmetic

lint: venv
	$(BIN)/ruff check livox_viz widgets tests benchmarks

bench: venv
	@for script in benchmarks/bench_*.py; do echo "== $$script"; $(BIN)/python $$script || exit 1; done

# The GUI image test's reference images, renewed on purpose (the test itself only compares): look at them after.
baselines: venv
	$(BIN)/python -m tests.baseline_images

# Mutation run (slow: not part of `make test` or CI). MUTATE_ARGS, e.g. "--sample 400 --seed 3" or "--bugs-only".
mutate: venv
	$(BIN)/python scripts/mutate.py $(MUTATE_ARGS)

screenshots: venv
	$(BIN)/livox-viz render --view both --seconds 1 --preset livox_mid70_fitted --reference livox_mid70_risley --out screenshots/both.png
	$(BIN)/livox-viz render --view pattern --seconds 1 --size 900x900 --out screenshots/pattern.png
	$(BIN)/livox-viz render --view scene --seconds 2 --trajectory line --trajectory-speed 6 --size 900x900 --out screenshots/scene.png
	$(BIN)/livox-viz render --view scene --seconds 1 --preset livox_mid70_risley --returns datasheet --scene-colour reflectivity --size 900x600 --out screenshots/returns-reflectivity.png
	$(BIN)/livox-viz render --view scene --seconds 1 --preset livox_mid70_risley --returns datasheet --scene-colour return/tag --size 900x600 --out screenshots/returns-tag.png

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache
