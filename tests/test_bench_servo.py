"""The servo benchmarks as commands that print figures: bench loop, bench stall, bench hotpath."""
import json

from conftest import assert_one_line_error


def test_bench_loop_reports_servo_and_bare_loop_timing_with_the_simulators_share_apart(run_cli):
    result = run_cli("bench", "loop", "--seconds", "0.3", "--json")
    assert result.returncode == 0, result.stderr
    figures = json.loads(result.stdout)
    for name in ("loop", "bare_loop"):
        loop = figures[name]
        assert loop["rate_hz"] == 1000.0 and 200 <= loop["ticks"] <= 400
        assert set(loop["lateness_us"]) == {"p50", "p99", "p999", "max"}
        assert {"p50", "p99"} <= set(loop["compute_us"])
        assert 0 <= loop["lateness_us"]["p50"] <= loop["lateness_us"]["max"]
    loop = figures["loop"]
    assert loop["compute_us"]["p50"] > figures["bare_loop"]["compute_us"]["p50"]
    assert loop["sim_us"]["p50"] > 0 and loop["host_us"]["p50"] > 0  # the simulated bridge + DAQ run inside the tick
    assert loop["host_us"]["p50"] < loop["compute_us"]["p50"]
    assert figures["scene"] == "bench"  # the default tissue (--scene names another, a 3-D one too)


def test_bench_loop_refuses_a_bad_length(run_cli):
    assert_one_line_error(run_cli("bench", "loop", "--seconds", "-1"), "--seconds")


def test_bench_loop_refuses_a_scene_it_cannot_find(run_cli):
    assert_one_line_error(run_cli("bench", "loop", "--seconds", "0.3", "--scene", "no-such-scene"), "no-such-scene")


def test_bench_stall_prints_outcome_true_force_and_motion_after_the_stop_per_pattern(run_cli):
    result = run_cli("bench", "stall", "--pattern", "5/1000", "--pattern", "150", "--json")
    assert result.returncode == 0, result.stderr
    figures = json.loads(result.stdout)
    ridden, stalled = figures["patterns"]
    assert ridden["pattern"] == "5 ms every 1000 ticks" and ridden["outcome"] == "completed"
    assert stalled["pattern"] == "150 ms once" and stalled["fault"]["code"] == "loop_stall"
    for row in (ridden, stalled):
        assert 0 < row["true_peak_n"] <= figures["cap_n"] and row["outside_workspace_mm"] == 0.0
        assert row["moved_after_stop_mm"] < 0.01 and row["pressing_after_stop_n"] == 0.0



def test_bench_stall_prints_a_row_per_pattern(capsys, monkeypatch):
    """The table's layout (the figures themselves are the JSON test's): one row per pattern, units on each."""
    from argparse import Namespace

    from palpd.commands import bench_stall

    def canned(settings, pattern, points_mm=None):
        return {"pattern": pattern.name, "outcome": "completed", "true_peak_n": 3.25, "host_peak_n": 3.26,
                "outside_workspace_mm": 0.0, "moved_after_stop_mm": 0.0, "pressing_after_stop_n": 0.0}

    monkeypatch.setattr(bench_stall, "run_pattern", canned)
    assert bench_stall.run(Namespace(pattern=["0", "20/200"], json=False, config=None)) == 0
    header, *rows, footer = capsys.readouterr().out.splitlines()
    assert "true peak" in header and "moved after stop" in header and "force cap 6.0 N" in footer
    assert [r.split("  ")[0] for r in rows] == ["no stall", "20 ms every 200 ticks"]
    assert all("3.25 N" in r and "completed" in r for r in rows)


def test_bench_stall_refuses_a_bad_pattern(run_cli):
    assert_one_line_error(run_cli("bench", "stall", "--pattern", "5/x"), "--pattern", "GAP_MS/EVERY_TICKS")


def test_bench_hotpath_prints_plain_float_and_numpy_figures_for_the_same_math(run_cli):
    result = run_cli("bench", "hotpath", "--ticks", "300", "--json")
    assert result.returncode == 0, result.stderr
    figures = json.loads(result.stdout)
    assert figures["ticks"] == 300 and figures["plain_floats_us_per_tick"] > 0 and figures["numpy_us_per_tick"] > 0
    assert figures["max_current_difference_a"] < 1e-9  # the two versions compute the same currents


def test_bench_hotpath_refuses_a_bad_tick_count(run_cli):
    assert_one_line_error(run_cli("bench", "hotpath", "--ticks", "5"), "--ticks")
