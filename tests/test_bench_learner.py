"""The learner benchmark runs and prints the figures DESIGN.md names (not a timing test)."""
import json


def test_bench_learner_json_has_the_contract_fields(run_cli):
    result = run_cli("bench", "learner", "--points", "30", "--grid", "31", "--json")
    assert result.returncode == 0, result.stderr
    out = json.loads(result.stdout)
    assert out["points"] == 30 and out["grid"] == 31
    assert 0 < out["update_ms"]["p50"] <= out["update_ms"]["max"]
    assert out["sklearn_refit_predict_ms"]["p50"] > 0
