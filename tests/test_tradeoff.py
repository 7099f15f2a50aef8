"""palpd bench tradeoff: scans as users run them, as tasks on a real Dask cluster (a scheduler and a worker
started as processes, as a user would by hand) and on the process pool that stands in without distributed."""
import csv
import os
import subprocess
import sys
import time

import pytest
from hypothesis import given, strategies as st

from conftest import SCENES
from palpd import metrics
from palpd.tradeoff import pareto, schedulers
from palpd.tradeoff.runs import COLUMNS

TINY_GRID = """
[[run]]
strategy = "raster"
palpations = 1

[[run]]
strategy = "active"
palpations = 2
settings = { learner = { tolerance_mm = 2.0 } }

[[run]]
strategy = "active"
palpation = "sliding"
palpations = 1
settings = { palpation = { sliding_length_mm = 6.0 } }
"""


@pytest.fixture(scope="module")
def dask_cluster(tmp_path_factory):
    """`dask scheduler` and one `dask worker` on loopback, random ports; yields the scheduler's address."""
    pytest.importorskip("distributed", reason="the cluster extra (distributed) is not installed")
    where = tmp_path_factory.mktemp("dask")
    scheduler_file = where / "scheduler.json"
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    common = ["--no-dashboard", "--scheduler-file", str(scheduler_file)]
    scheduler = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                                  "--port", "0", *common], cwd=where, env=env, stderr=subprocess.DEVNULL)
    worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", "--host", "127.0.0.1",
                               "--no-nanny", "--nthreads", "1", *common], cwd=where, env=env,
                              stderr=subprocess.DEVNULL)
    try:
        yield _address(scheduler_file)
    finally:
        for process in (worker, scheduler):
            process.terminate()
            process.wait(timeout=30)


def _address(scheduler_file, wait_s: float = 30.0) -> str:
    import json

    deadline = time.monotonic() + wait_s
    while time.monotonic() < deadline:
        try:
            return json.loads(scheduler_file.read_text())["address"]
        except (FileNotFoundError, ValueError, KeyError):
            time.sleep(0.1)  # the scheduler writes its file once it listens: nothing to await but the file
    raise AssertionError("the dask scheduler did not start")


@pytest.fixture(scope="module")
def cluster_sweep(dask_cluster, tmp_path_factory):
    """The Done-when command, on a tiny grid: (exit code, output dir, rows as read back)."""
    from palpd.cli import main

    out = tmp_path_factory.mktemp("sweep")
    (out / "grid.toml").write_text(TINY_GRID)
    code = main(["bench", "tradeoff", "--scenes", str(SCENES / "paper.toml"), "--seeds", "2", "--grid",
                 str(out / "grid.toml"), "--scheduler", dask_cluster, "--out", str(out)])
    with open(out / "tradeoff.csv", newline="") as f:
        return code, out, list(csv.DictReader(f))


def test_a_sweep_on_a_dask_cluster_writes_the_rows_and_the_front(cluster_sweep):
    code, out, rows = cluster_sweep
    assert code == 0 and not (out / "failures.csv").exists()
    assert list(rows[0]) == COLUMNS and len(rows) == 6  # 2 seeds × 3 settings, in the grid's order
    entries = [("raster", "discrete", "n=1"), ("active", "discrete", "n=2;tolerance_mm=2.0"),
               ("active", "sliding", "n=1;sliding_length_mm=6.0")]
    assert [(r["seed"], r["strategy"], r["palpation"], r["setting"]) for r in rows] == [
        (seed, *entry) for seed in "01" for entry in entries]
    assert all(r["lumps_true"] == "1" for r in rows)
    assert [r["palpations"] for r in rows if r["palpation"] == "discrete"] == ["1", "2", "1", "2"]  # own budgets
    assert all(int(r["palpations"]) >= 2 for r in rows if r["palpation"] == "sliding")  # readings along one path
    assert (out / "pareto.png").stat().st_size > 10_000 and (out / "settings.csv").exists()


def test_the_process_pool_gives_the_cluster_its_rows_and_failures_stay_per_run(cluster_sweep, monkeypatch):
    """Without distributed, `local` is a process pool: same rows; a run whose scene map is missing where the
    task runs fails alone, and says why."""
    from drivers.sim.scene import load_scene
    from palpd.config import Settings
    from palpd.tradeoff import grid
    from palpd.tradeoff.runs import run_one

    _, out, cluster_rows = cluster_sweep
    paper = load_scene(SCENES / "paper.toml")
    lost = paper.model_copy(update={"tissue": paper.tissue.model_copy(update={"map": str(out / "gone.csv")})})
    runs = grid.runs([paper, lost], 2, grid.load_grid(out / "grid.toml"), Settings())
    monkeypatch.setattr(schedulers, "has_distributed", lambda: False)
    results = schedulers.execute(run_one, runs[4:6] + runs[-3:-2], "local", workers=1)  # seed 1, a lost map
    as_csv = [{k: "" if v is None else str(v) for k, v in row.items()} for row, _ in results[:2]]
    assert as_csv == cluster_rows[4:]  # the learner's scans, discrete and sliding, alike to the last digit
    assert results[2][0] is None and "gone.csv" in results[2][1]


def test_a_failing_task_on_the_cluster_is_reported_as_its_own(dask_cluster):
    results = schedulers.execute(int, ["7", "not a number"], dask_cluster)
    assert results[0] == (7, None) and results[1][0] is None and results[1][1].startswith("ValueError")


def test_a_scheduler_that_is_not_an_address_is_a_usage_error():
    from palpd.errors import UsageError

    with pytest.raises(UsageError, match="--scheduler"):
        schedulers.execute(int, ["1"], "somewhere")


_line = st.fixed_dictionaries({"robot_time_s": st.floats(1, 100), "iou": st.floats(0, 1),
                               "center_error_mm": st.one_of(st.floats(0, 20), st.just(float("inf")))})


@given(st.lists(_line, min_size=1, max_size=12))
def test_the_front_holds_exactly_the_settings_no_other_beats(lines):
    summary = [{**line, "strategy": "s", "palpation": "discrete", "setting": str(i)} for i, line in enumerate(lines)]
    for metric, sign in (("iou", 1), ("center_error_mm", -1)):
        for line in summary:
            beaten = any(pareto._dominates(other, line, metric, sign) for other in summary)
            assert pareto._on_front(line, summary, metric, sign) == (not beaten and line[metric] != float("inf"))
        assert any(pareto._on_front(line, summary, "iou", 1) for line in summary)


def test_region_iou_counts_missed_and_false_lumps_as_area():
    true = [{"center_mm": [0.0, 0.0], "radius_mm": 5.0}, {"center_mm": [15.0, 0.0], "radius_mm": 5.0}]
    square = [[-5.0, -5.0], [5.0, -5.0], [5.0, 5.0], [-5.0, 5.0]]
    one = metrics.region_iou(true, [{"boundary_mm": square}], (60.0, 60.0))
    assert one == pytest.approx(3.14159 * 25 / (100 + 3.14159 * 25), abs=0.03)  # the missed lump halves it
    assert metrics.region_iou([], [], (60.0, 60.0)) == 1.0
    assert metrics.region_iou([], [{"boundary_mm": square}], (60.0, 60.0)) == 0.0


def test_the_plot_of_a_sweep_on_scenes_without_lumps_is_drawn(tmp_path):
    """No centre error anywhere (no lump to be off): the log scale had nothing to scale and the sweep died
    after writing its CSVs, without a plot."""
    rows = [{"scene": "no-lump", "seed": 0, "strategy": strategy, "palpation": palpation, "setting": "default",
             "palpations": 10, "robot_time_s": 18.5 + i, "center_error_mm": None, "radius_error_mm": None,
             "iou": 1.0, "lumps_found": 0, "lumps_true": 0}
            for i, (strategy, palpation) in enumerate(pareto.COLOURS)]
    pareto.plot(rows, pareto.settings_summary(rows), tmp_path / "pareto.png")
    assert (tmp_path / "pareto.png").read_bytes().startswith(b"\x89PNG")


def test_the_calibration_bench_scores_the_stated_error_against_the_truth_on_the_cluster(dask_cluster, tmp_path, capsys):
    """palpd bench calibration (issue 48): the paper scene at a 2 mm tolerance, as a user runs it, on the cluster."""
    import json

    from palpd.cli import main

    code = main(["bench", "calibration", "--scenes", str(SCENES / "paper.toml"), "--tolerances", "2",
                 "--scheduler", dask_cluster, "--out", str(tmp_path), "--json"])
    assert code == 0
    (row,) = json.loads(capsys.readouterr().out)["settings"]
    assert row["tolerance_mm"] == 2.0 and row["confidence"] == 0.9 and row["runs"] == 1
    assert row["count_right"] == 1.0 and row["wrong_count_verdicts"] == 0 and row["within_tolerance"] == 1.0
    assert row["wrong_beyond_claim"] == 0
    assert 0.0 <= row["boundary_error_mm"] <= 2.0 and 0.0 < row["stated_error_mm"] <= 2.0
    with open(tmp_path / "calibration.csv", newline="") as f:
        (written,) = list(csv.DictReader(f))
    assert written["verdict"] == "lumps" and float(written["boundary_error_mm"]) == row["boundary_error_mm"]
    assert float(written["unfelt_radius_mm"]) > 0 and written["wrong_beyond_claim"] == "0"


def test_the_reliability_table_counts_wrong_verdicts_and_errors_within_the_tolerance():
    from palpd.commands.bench_calibration import format_table, reliability

    def run(found, false, verdict, error, palpations=20, setting="tolerance_mm=0.5;confidence=0.9", beyond=None):
        return {"setting": setting, "lumps_found": found, "lumps_true": 1, "false_lumps": false, "verdict": verdict,
                "boundary_error_mm": error, "expected_boundary_error_mm": 0.1, "palpations": palpations,
                "wrong_beyond_claim": false + (1 - found) if beyond is None else beyond}
    # the fourth: `none` with a lump missed under the stated unfelt radius, a wrong count within the verdict's claim
    rows = [run(1, 0, "lumps", 0.2), run(1, 1, "lumps", 0.7, 30), run(0, 0, "undetermined", 5.0, 40),
            run(0, 0, "none", None, 20, beyond=0), run(1, 0, "lumps", 0.4, 10, "tolerance_mm=2.0;confidence=0.9")]
    tight, loose = reliability(rows)
    assert (tight["runs"], tight["palpations"], tight["wrong_count_verdicts"], tight["undetermined"]) == (4, 110, 2, 1)
    assert tight["wrong_beyond_claim"] == 1  # the false lump; not the lump the `none` verdict allowed for
    assert tight["count_right"] == pytest.approx(1 / 4) and tight["within_tolerance"] == pytest.approx(1 / 3)
    assert (tight["claimed"], tight["claimed_and_within"]) == (2, 1)  # the undetermined run claimed nothing
    assert loose["tolerance_mm"] == 2.0 and loose["within_tolerance"] == 1.0 and loose["wrong_beyond_claim"] == 0
    assert "| 0.5 | 0.9 | 110 | 25 | 25% | 2 | 1 | 1 |" in format_table([tight, loose], 4, 0)


@pytest.mark.parametrize("args, says", [(["--tolerances", "abc"], "--tolerances abc"),
                                        (["--tolerances", "0,1"], "positive"),
                                        (["--confidences", "1.5"], "--confidences")])
def test_bad_calibration_settings_are_one_line(args, says):
    done = subprocess.run([sys.executable, "-m", "palpd", "bench", "calibration", *args], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode != 0 and says in done.stderr and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr
