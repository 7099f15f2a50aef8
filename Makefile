# Two commands do everything on a fresh machine with Python 3.11+ and make.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
OUT := out

.PHONY: run test reproduce clean

$(BIN)/palpd: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

run: $(BIN)/palpd
	mkdir -p $(OUT)
	$(BIN)/palpd scan --scene config/scenes/paper.toml --strategy active \
		--report $(OUT)/paper-report.json --plot $(OUT)/paper-map.png

# Two workers: the suite's scans, daemons and subprocesses spend most of their time in one Python each;
# each module stays on one worker, and the wall-clock modules share one (tests/conftest.py).
# PYTHONDONTWRITEBYTECODE emptied: the suite starts ~150 Python processes (CLIs, daemons, servo processes),
# and with bytecode caching off (some shells set it) each compiles palpd afresh (~0.1 s of CPU each).
test: $(BIN)/palpd
	PYTHONDONTWRITEBYTECODE= $(BIN)/python -m pytest -n 2

reproduce: $(BIN)/palpd
	$(BIN)/python scripts/reproduce.py

clean:
	rm -rf $(VENV) $(OUT) build *.egg-info
