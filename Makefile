# Two commands do everything on a fresh machine with Python 3.11+ and make.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
OUT := out

.PHONY: run test reproduce figures tables docs clean

# setuptools notes every editable install of a mapped layout (config/ ships as palpd.share) at length:
# informational only, so hidden. pip at -qq says only errors: a first `make run` printed its warnings about
# the host's own package-index settings (dozens of "Location ... is ignored"), nothing about palpd, first.
$(BIN)/palpd: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -qq --upgrade pip
	PYTHONWARNINGS="ignore:Editable installation" $(BIN)/python -m pip install -qq -e '.[test]'
	touch $@

run: $(BIN)/palpd
	mkdir -p $(OUT)
	$(BIN)/palpd scan --scene config/scenes/paper-3d.toml --strategy active \
		--report $(OUT)/paper-3d-report.json --plot $(OUT)/paper-3d-map.png

# Three workers on two cores: the suite is CPU-bound, and beside another busy process (a CPU hog) a third
# worker takes 3/4 of the cores' share instead of 2/3 (five runs beside a hog: 155-158 s with two, 145-153 s
# with three; idle 116 -> 107 s; four workers gave 149 s, no better). Each module stays on one worker, and the wall-clock modules
# share one (tests/conftest.py), so two real-time loops never run at once.
# PYTHONDONTWRITEBYTECODE emptied: the suite starts ~150 Python processes (CLIs, daemons, servo processes),
# and with bytecode caching off (some shells set it) each compiles palpd afresh (~0.1 s of CPU each).
test: $(BIN)/palpd
	PYTHONDONTWRITEBYTECODE= $(BIN)/python -m pytest -n 3

reproduce: $(BIN)/palpd
	$(BIN)/python scripts/reproduce.py

# The shipped 3-D scenes' force tables (drivers/sim/mechanics/tables/), rebuilt where a scene or the recipe changed.
tables: $(BIN)/palpd
	$(BIN)/python scripts/build_force_tables.py

# The tables and pictures the README and the manual include, measured here and stamped with the commit.
figures: $(BIN)/palpd
	$(BIN)/python scripts/figures.py

# The manual, into site/ (the docs extra: mkdocs, Material, mkdocstrings; the test extra brings them too).
docs: $(BIN)/palpd
	$(BIN)/mkdocs build --strict

clean:
	rm -rf $(VENV) $(OUT) build site *.egg-info
