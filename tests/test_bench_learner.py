"""The learner benchmark runs and prints the figures DESIGN.md names (not a timing test)."""
import json


def test_bench_learner_json_has_the_contract_fields_and_both_baselines(run_cli):
    result = run_cli("bench", "learner", "--points", "30", "--grid", "21", "--json")
    assert result.returncode == 0, result.stderr
    out = json.loads(result.stdout)
    assert out["points"] == 30 and out["grid"] == 21
    assert 0 < out["update_ms"]["p50"] <= out["update_ms"]["max"] <= out["spikes"]["max_ms"]
    assert out["spikes"]["to_points"] >= 30
    cpu = out["update_cpu_ms"]
    assert 0 <= cpu["p50"] <= cpu["max"] <= cpu["max_to_spikes"] and 0 <= cpu["over_50_ms"] <= out["spikes"]["to_points"]
    assert out["sklearn_fixed_kernel_ms"]["p50"] > 0 and out["sklearn_optimised_ms"]["p50"] > 0
    assert out["blas_threads"] == 1  # palpd pins BLAS to one thread in its own processes
