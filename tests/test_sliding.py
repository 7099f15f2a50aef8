"""Sliding palpation on the simulated bench: the stiffness read while sliding agrees with a discrete
palpation at the same spot, the tissue drags the sliding tip (Coulomb friction), and a lateral-force stop
lifts the probe off without sliding on."""
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from conftest import SCENES
from drivers.sim.scene import Scene, load_scene
from drivers.sim.tissue import SLIP_MM_S, StiffnessField, sliding_friction_n
from palpd.bench import open_simulated_bench
from palpd.config import Settings
from palpd.control.sliding import SlidingPalpation
from palpd.control.tasks import HoldAndCollect, MoveTo
from palpd.learner.paths import _clipped
from palpd.errors import ScanFault
from palpd.scan import palpate
from palpd.slide import slide
from palpd.stiffness.sliding import _cycle_point, _halves_spread, stiffness_points
from test_faults import Watch

FRICTION = 0.3  # a wet tissue under a smooth probe
AGREEMENT = 0.03  # sliding vs discrete stiffness at the same spot, away from an edge (default sliding settings)


@pytest.fixture(scope="module")
def paper_bench():
    settings, paper = Settings(), load_scene(SCENES / "paper.toml")
    scene = paper.model_copy(update={"tissue": paper.tissue.model_copy(update={"friction": FRICTION})})
    bench = open_simulated_bench(settings, scene, seed=0)
    p = settings.palpation
    bench.servo.start()
    start = (-25.0, -4.0, p.clearance_mm)
    bench.servo.run(MoveTo(start, p.travel_speed_mm_s, p.accel_mm_s2))
    tare = HoldAndCollect(p.tare_samples, where=start)
    bench.servo.run(tare)
    bench.servo.forces.tare(tare.samples)
    return settings, bench


def test_sliding_reads_what_a_discrete_palpation_reads_at_the_same_spot(paper_bench):
    settings, bench = paper_bench
    probes = slide(bench, settings, ((-25.0, -4.0), (12.0, -4.0)))  # background, the lump's edge, its top
    assert len(probes) >= 10 and all(p.outcome == "fit" for p in probes)
    assert probes[0].record.stop_reason == "path_end"
    for x_mm in (-20.0, 7.5):  # the background and the lump's flat top, 7 mm from its 50 % edge
        near = min(probes, key=lambda p: abs(p.record.xy_mm[0] - x_mm))
        pressed = palpate(bench, settings, near.record.xy_mm)
        assert near.stiffness_n_per_mm == pytest.approx(pressed.stiffness_n_per_mm, rel=AGREEMENT)
        assert 0 < near.fit.stiffness_se_n_per_mm < 0.05 * near.stiffness_n_per_mm
    readings = [p.stiffness_n_per_mm for p in probes]
    assert max(readings) > 5 * min(readings)  # the edge crossed within the path is in the stream
    edge = min(probes, key=lambda p: abs(p.record.xy_mm[0] + 2.5))  # the lump's 50 % edge (x = 7.5 - 10)
    flat = min(probes, key=lambda p: abs(p.record.xy_mm[0] + 20.0))
    assert edge.fit.stiffness_se_n_per_mm > 5 * flat.fit.stiffness_se_n_per_mm  # it averages a changing span


def test_the_tissue_drags_the_sliding_tip_and_the_drag_is_measured(paper_bench):
    settings, bench = paper_bench
    task = SlidingPalpation((-25.0, 20.0), (-5.0, 20.0), settings.palpation)  # background: ~0.3 N pressed
    bench.servo.run(task)
    normal = sum(task.record.force_n) / len(task.record.force_n)
    friction = FRICTION
    assert friction * normal * 0.5 < task.record.max_lateral_n < friction * task.record.max_force_n * 1.5 + 0.05
    assert len(stiffness_points(task.record, settings.palpation)) >= 5


@given(st.floats(0.0, 10.0), st.floats(0.0, 2.0), st.floats(-100, 100), st.floats(-100, 100))
def test_friction_opposes_the_motion_and_never_exceeds_coulomb(normal_n, mu, vx, vy):
    fx, fy = sliding_friction_n(normal_n, mu, vx, vy)
    assert math.hypot(fx, fy) <= mu * normal_n + 1e-9
    assert fx * vx + fy * vy <= 1e-12  # never pushes the tip along
    if math.hypot(vx, vy) > 10 * SLIP_MM_S:
        assert math.hypot(fx, fy) >= 0.99 * mu * normal_n - 1e-12  # (a subnormal μ underflows to none)


def test_a_lateral_force_stop_lifts_the_probe_off_without_sliding_on():
    settings = Settings().updated(safety={"max_lateral_force_n": 0.4})  # a limit tighter than the default
    bench = open_simulated_bench(settings, Scene(name="stiff", tissue={"stiffness_n_per_mm": 0.8, "friction": 0.3}))
    bench.servo.start()  # a stiff tissue: ~2 N pressed, ~0.6 N of drag at μ = 0.3
    watch = Watch(bench)
    with pytest.raises(ScanFault):
        bench.servo.run(SlidingPalpation((0.0, 0.0), (20.0, 0.0), settings.palpation))
    fault = bench.servo.fault
    assert fault.code == "lateral_force" and fault.category == 1
    watch.no_press_nor_slide_after_the_fault()
    assert bench.world.contact_force_n == 0.0 and bench.world.tip_mm()[2] > 0.0
    assert bench.world.amplifiers_on is False


def test_a_slide_pressing_into_tissue_too_stiff_for_its_depth_lifts_at_the_force_limit_not_at_the_cap():
    """12 N/mm: the force limit (4 N) comes a third of a millimetre in, long before the sliding depth. The press
    went on past it, the tip chattering on the surface, to the safety supervisor's 6 N cap (a force_cap fault
    ended the scan); it lifts off at the limit now, as the slide itself and a discrete press do."""
    settings = Settings()
    bench = open_simulated_bench(settings, Scene(name="very-stiff", tissue={"stiffness_n_per_mm": 12.0}))
    bench.servo.start()
    task = SlidingPalpation((0.0, 0.0), (20.0, 0.0), settings.palpation)
    bench.servo.run(task)  # no ScanFault
    assert task.done and task.record.stop_reason == "force" and bench.servo.fault is None
    assert bench.world.max_contact_force_n < settings.safety.force_cap_n
    assert bench.world.contact_force_n == 0.0 and bench.world.tip_mm()[2] > 0.0  # lifted off, not pressing


def _tared(scene, start_xy):
    settings = Settings()
    bench = open_simulated_bench(settings, scene, seed=0)
    p = settings.palpation
    bench.servo.start()
    above = (*start_xy, p.clearance_mm)
    bench.servo.run(MoveTo(above, p.travel_speed_mm_s, p.accel_mm_s2))
    tare = HoldAndCollect(p.tare_samples, where=above)
    bench.servo.run(tare)
    bench.servo.forces.tare(tare.samples)
    return settings, bench


def test_a_path_stopped_on_a_stiff_edge_states_what_its_last_reading_spans():
    """stiff-tissue: a path from the 2 N/mm tissue towards the 12 N/mm lump meets the force limit just inside
    its edge. Its last full cycle ran onto the edge in its final millimetre, and the straight line in s the
    cycle is fitted with spread that step thin: 2.66 ± 0.08 N/mm where the tissue under the cycle's mean
    position is 2.0, and active sliding scans drew four false lumps to explain such readings. Every sliding
    reading must hold the tissue under its position within 3 of its standard errors."""
    scene = load_scene(SCENES / "stiff-tissue.toml")
    start, end = (20.67, -8.18), (-10.0, 6.0)
    settings, bench = _tared(scene, start)
    probes = slide(bench, settings, (start, end))
    field = StiffnessField(scene)
    sliding = [p for p in probes if p.fit is not None and p.fit.model == "sliding-linear"]
    assert len(sliding) >= 4 and any(p.record.stop_reason == "force" for p in sliding)
    for probe in sliding:
        truth = field.k_at(*probe.record.xy_mm)
        assert abs(probe.stiffness_n_per_mm - truth) <= 3.0 * probe.fit.stiffness_se_n_per_mm, probe.record.xy_mm
    assert any(field.k_at(*p.record.xy_mm) < 2.1 < p.stiffness_n_per_mm - 0.3 for p in sliding)  # the edge's reading


def test_a_row_across_a_lump_too_stiff_to_slide_on_reads_it_and_goes_on_past_it():
    """A raster row of stiff-tissue meets the force limit at the 12 N/mm lump's edge. It ended there: the lump
    was felt only at its edges, and a sliding raster said `none` once those readings stated their spread. Now
    each spot the limit lifts it at is pressed (a discrete palpation, like any pressed spot) and the path
    touches down a cycle's span further on, until it is past the lump and slides again: the lump's inside is
    read, the row is read to its end, and no force comes near the safety cap."""
    scene = load_scene(SCENES / "stiff-tissue.toml")
    start, end = (-25.0, 6.0), (25.0, 6.0)
    settings, bench = _tared(scene, start)
    probes = slide(bench, settings, (start, end))
    field = StiffnessField(scene)
    pressed = [p for p in probes if p.fit is None or p.fit.model != "sliding-linear"]
    inside = [p for p in pressed if field.k_at(*p.record.xy_mm) > 10.0]
    assert len(inside) >= 3
    assert all((p.stiffness_n_per_mm or p.stiffness_bound_n_per_mm) > 6.0 for p in inside)
    assert max(p.record.xy_mm[0] for p in probes if p.fit is not None and p.fit.model == "sliding-linear") > 20.0
    assert bench.servo.fault is None and bench.world.max_contact_force_n < settings.safety.force_cap_n
    assert bench.world.contact_force_n == 0.0  # lifted off at the end


def test_a_cycle_on_even_tissue_keeps_its_precision():
    """On even tissue a cycle's two halves differ by their noise alone, and only a difference beyond it widens
    the reading's error: over many noisy cycles most gain nothing (a χ² of one degree of freedom stays under
    its mean two times in three) and none gains more than a few times its own noise."""
    rng = np.random.default_rng(3)
    t = np.arange(100) / 1000.0
    depth = 1.5 + 0.5 * np.sin(2.0 * np.pi * 10.0 * t)
    spreads = np.array([_halves_spread(depth, 2.0 * depth + rng.normal(0.0, 0.01, depth.size)) for _ in range(300)])
    assert np.mean(spreads == 0.0) > 0.55
    assert spreads.max() < 0.03  # each half's slope is known to ~0.01 N/mm


def test_a_path_whose_press_meets_the_force_limit_is_read_as_pressed_spots_along_it():
    """Pressed to its sliding depth on 12 N/mm, the force limit comes before the slide can begin. That path was
    `rejected` (no cycle read); now each spot is read as every pressed spot is, a discrete palpation (its
    stiffness fitted up to the limit, or a bound), a cycle's span apart along the path."""
    scene = Scene(name="very-stiff", tissue={"stiffness_n_per_mm": 12.0})
    settings, bench = _tared(scene, (0.0, 0.0))
    probes = slide(bench, settings, ((0.0, 0.0), (20.0, 0.0)))
    p = settings.palpation
    assert len(probes) == math.ceil(20.0 / (p.sliding_speed_mm_s / p.modulation_hz))
    assert all(probe.outcome in ("fit", "too_stiff") for probe in probes)
    assert all((probe.stiffness_n_per_mm or probe.stiffness_bound_n_per_mm) > 6.0 for probe in probes)
    assert bench.servo.fault is None and bench.world.contact_force_n == 0.0


@settings(max_examples=6, deadline=None)
@given(st.floats(3.0, 80.0), st.floats(0.5, 6.0), st.floats(-8.0, 8.0))
def test_a_path_across_a_lump_of_any_stiffness_ends_lifted_without_a_fault(lump_n_per_mm, tissue_n_per_mm, offset_mm):
    """Extremes through the simulator: from a lump a little stiffer than its tissue to one 80 N/mm in soft
    tissue, a path across it (through its centre or off to one side) ends lifted off, with no safety fault
    and no force near the cap, and every spot read is a sliding cycle or a pressed spot: the presses a
    cycle's span apart at most, so a path is never read more densely than its cycles would read it."""
    scene = Scene(name="lump", tissue={"stiffness_n_per_mm": tissue_n_per_mm},
                  lump=[{"center_mm": [0.0, offset_mm], "radius_mm": 6.0, "stiffness_n_per_mm": lump_n_per_mm}])
    settings, bench = _tared(scene, (-12.0, 0.0))
    probes = slide(bench, settings, ((-12.0, 0.0), (12.0, 0.0)))
    p = settings.palpation
    pressed = [probe for probe in probes if probe.fit is None or probe.fit.model != "sliding-linear"]
    assert len(pressed) <= math.ceil(24.0 / (p.sliding_speed_mm_s / p.modulation_hz)) + 1
    assert all(probe.outcome in ("fit", "too_stiff", "too_soft", "rejected", "no_contact") for probe in probes)
    assert bench.servo.fault is None and bench.world.max_contact_force_n < settings.safety.force_cap_n
    assert bench.world.contact_force_n == 0.0


def test_a_slow_path_over_tissue_too_stiff_to_slide_on_is_pressed_a_spacing_apart_not_without_end():
    """At 0.01 mm/s and 10 Hz a cycle spans a micrometre: stepping on by a cycle's span past each pressed spot,
    a 6 mm path over 12 N/mm tissue would have been pressed some 6000 times. The spots are the learner's
    minimum spacing apart (1.5 mm) at least."""
    scene = Scene(name="very-stiff", tissue={"stiffness_n_per_mm": 12.0})
    settings, bench = _tared(scene, (0.0, 0.0))
    settings = settings.updated(palpation={"sliding_speed_mm_s": 0.01})
    probes = slide(bench, settings, ((0.0, 0.0), (6.0, 0.0)))
    assert 2 <= len(probes) <= math.ceil(6.0 / settings.learner.min_spacing_mm)
    assert all(probe.outcome in ("fit", "too_stiff") for probe in probes)


def test_a_scan_a_safety_fault_cut_short_claims_no_count():
    """0.3 N of noise: a sliding raster's fourth path went past the indentation limit and the fault ended the
    scan after a few rows, with "none" claimed for the whole tissue from them (a wrong count: the lump lay in
    rows never read). A plan a fault cut short decides nothing: `undetermined`, and why."""
    from palpd.scan import plan, run_scan

    settings = Settings().updated(scan={"strategy": "raster"}, palpation={"mode": "sliding"})
    scene = load_scene(SCENES / "very-noisy-sensor.toml")
    planner = plan("raster", scene.tissue.size_mm, settings.scan.max_palpations, 0, settings)
    report = run_scan(open_simulated_bench(settings, scene, seed=0), settings, planner)
    assert [f["code"] for f in report["faults"]] == ["indentation"]
    assert report["verdict"] == "undetermined" and "indentation" in report["undetermined_reason"]


def test_a_noisy_sensor_does_not_fake_the_surface_a_slide_presses_from():
    """At 0.08 N of noise a raw sample above the 0.03 N floor comes on almost every approach: judged on the
    low-passed force against thresholds scaled to the tare's noise, contact is the surface, and the path reads."""
    settings, scene = Settings(), load_scene(SCENES / "noisy-sensor.toml")
    bench = open_simulated_bench(settings, scene, seed=0)
    p = settings.palpation
    bench.servo.start()
    start = (-25.0, 20.0, p.clearance_mm)
    bench.servo.run(MoveTo(start, p.travel_speed_mm_s, p.accel_mm_s2))
    tare = HoldAndCollect(p.tare_samples, where=start)
    bench.servo.run(tare)
    bench.servo.forces.tare(tare.samples)
    for y_mm in (20.0, 24.0):  # background, ~0.3 N pressed
        probes = slide(bench, settings, ((-25.0, y_mm), (-10.0, y_mm)))
        assert len(probes) >= 3 and all(pr.outcome == "fit" for pr in probes), [pr.rejected for pr in probes]
        assert probes[0].record.stop_reason == "path_end"
        assert abs(probes[0].record.contact_z_mm) < 1.0  # the surface (z = 0), not a noise spike above it
    bench.servo.stop()


@given(st.floats(5.0, 200.0), st.floats(5.0, 200.0), st.floats(0.0, 1.0), st.floats(0.0, 1.0),
       st.floats(-math.pi, math.pi), st.floats(1.0, 500.0))
def test_a_planned_path_passes_through_the_spot_asked_for_and_stays_on_the_tissue(width, height, fx, fy, angle,
                                                                                  length):
    """Slid sideways to fit (as it once was near the edges), a path missed the spot the learner asked for, which
    then asked for it again, path after path."""
    spot = ((fx - 0.5) * width, (fy - 0.5) * height)
    (x0, y0), (x1, y1) = _clipped(spot, angle, length, (width, height))
    assert all(abs(x) <= width / 2 + 1e-9 and abs(y) <= height / 2 + 1e-9 for x, y in ((x0, y0), (x1, y1)))
    span = math.dist((x0, y0), (x1, y1))
    assert span <= length + 1e-9
    assert abs((x1 - x0) * (spot[1] - y0) - (y1 - y0) * (spot[0] - x0)) <= 1e-6 * max(span, 1.0)  # on its line
    assert min(math.dist(spot, (x0, y0)), math.dist(spot, (x1, y1))) <= span + 1e-9  # between its ends


def test_a_sliding_scan_says_when_its_paths_met_the_force_limit(run_cli, tmp_path):
    """The stiff-tissue lump, 12 N/mm in 2 N/mm, is too stiff to slide across at sliding_depth_mm ±
    modulation_mm: the report counts the paths that met the limit, and the CLI says in one line what was done
    about it (the spots pressed instead, the path going on past them) and what it costs."""
    report = tmp_path / "report.json"
    result = run_cli("scan", "--scene", SCENES / "stiff-tissue.toml", "--strategy", "raster", "--max-palpations", "3",
                     "--palpation", "sliding", "--report", report)
    body = json.loads(report.read_text())
    assert body["paths_lifted_at_force_limit"] == 1  # the middle row of three
    assert any(probe["stiffness_model"] != "sliding-linear" and probe["stiffness_n_per_mm"] > 6.0
               for probe in body["probes"] if probe["outcome"] == "fit")  # the lump pressed
    notes = [line for line in result.stderr.splitlines() if "force limit" in line]
    assert len(notes) == 1 and "pressed instead" in notes[0] and "Traceback" not in result.stderr
    pressed_lines = [line for line in result.stderr.splitlines() if line.endswith("(pressed: too stiff to slide on)")]
    assert len(pressed_lines) == sum("contact_xy_mm" in probe for probe in body["probes"]) >= 3  # the presses
