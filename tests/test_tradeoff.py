"""The tradeoff benchmark's plumbing: scans stop once on target, through the planners' public interface only."""
from palpd.commands._tradeoff_runs import _UntilOnTarget, on_target
from palpd.scan import FixedPlan


def test_a_plan_wrapped_until_on_target_stops_when_told_and_passes_observations_on():
    seen = []
    inner = FixedPlan([(0.0, 0.0), (1.0, 0.0), (2.0, 0.0)])
    inner.observe = seen.append
    reached = []
    wrapped = _UntilOnTarget(inner, lambda: bool(reached))
    assert wrapped.expected_total == 3 and wrapped.next_probe() == (0.0, 0.0)
    wrapped.observe("probe")
    reached.append(True)
    assert wrapped.next_probe() is None and seen == ["probe"]


def test_on_target_needs_every_lump_no_false_one_and_each_accuracy():
    good = {"lumps_found": 1, "lumps_true": 1, "false_lumps": 0, "max_center_error_mm": 0.5,
            "max_radius_error_mm": 0.5, "min_iou": 0.95}
    assert on_target(good)
    assert not on_target({**good, "min_iou": 0.85}) and not on_target({**good, "false_lumps": 1})
    assert not on_target({**good, "max_center_error_mm": 1.2})
    assert on_target({"lumps_found": 0, "lumps_true": 0, "false_lumps": 0})
