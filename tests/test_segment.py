"""The segmenter finds every palpation of a hand-palpated session, and nothing else."""
import math
import random

import pytest
from hypothesis import given, settings as hsettings, strategies as st

from drivers.sim.hand import HandSession
from drivers.sim.scene import Scene
from palpd.bench import open_simulated_bench
from palpd.config import Settings
from palpd.control.segment import ManualSession, Segmenter
from palpd.stiffness import fit_linear


def expected_presses(hand):
    """(xy, t_from, t_to) for each press the hand made: a double tap is two."""
    presses = []
    for tap in hand.taps:
        p = tap.press_s
        if tap.double:
            presses += [(tap.xy_mm, tap.t_s, tap.t_s + 1.65 * p), (tap.xy_mm, tap.t_s + 1.65 * p, tap.t_s + 3.7 * p)]
        else:
            presses.append((tap.xy_mm, tap.t_s, tap.t_s + 2 * p))
    return presses


def hand_session(k=0.12, count=12, seed=5, drift_n_per_s=(0.0, 0.0, 0.02)):
    settings = Settings()
    bench = open_simulated_bench(settings, Scene(name="hand", tissue={"stiffness_n_per_mm": k},
                                                 sensor={"tilt": True, "noise_n": 0.01}), seed=seed)
    hand = HandSession.random(bench.world.frame, count, seed)
    bench.world.hand = hand
    bench.world.arm.q = list(hand.q_at(0.0))  # the person picked the probe up before the session
    bench.world.faults.sensor_drift_n_per_s = drift_n_per_s
    session = ManualSession(Segmenter(0.06, 0.03), hand.end_s + 0.3)  # untared and drifting: the manual floors
    bench.servo.start(home=False)  # the person holds the arm: it is not taken home
    bench.servo.run(session)  # not tared: the segmenter tracks the zero itself
    bench.servo.stop(park=False)  # the person holds the arm: power off where it is
    return hand, session


def test_every_hand_palpation_is_found_once_with_double_taps_and_drift():
    hand, session = hand_session()
    presses = expected_presses(hand)
    assert sum(t.double for t in hand.taps) >= 3
    assert len(session.segments) == len(presses)
    for segment, (xy, t_from, t_to) in zip(session.segments, presses):
        assert t_from <= segment.t_onset_s <= segment.t_end_s <= t_to + 0.05
        assert math.dist(segment.xy_mm, xy) < 0.5


def test_hand_palpations_give_the_tissue_stiffness():
    _, session = hand_session(k=0.3, count=6, seed=2, drift_n_per_s=(0.0, 0.0, 0.0))
    for segment in session.segments:
        assert fit_linear(segment.depth_mm, segment.force_n).stiffness_n_per_mm == pytest.approx(0.3, rel=0.05)


@hsettings(max_examples=40, deadline=None)
@given(noise_n=st.floats(0.0, 0.012), drift_n_per_s=st.floats(-0.05, 0.05), bias_n=st.floats(-3.0, 3.0),
       seed=st.integers(0, 1000))
def test_noise_drift_and_bias_alone_are_never_a_palpation(noise_n, drift_n_per_s, bias_n, seed):
    rng = random.Random(seed)
    segmenter = Segmenter(0.06, 0.03)
    found = [segmenter.push(i * 0.001, (0.0, 0.0, 5.0), bias_n + drift_n_per_s * i * 0.001 + rng.gauss(0, noise_n))
             for i in range(5000)]
    assert [f for f in found if f is not None] == []


def test_a_brush_too_slight_to_be_a_palpation_is_rejected():
    segmenter = Segmenter(0.06, 0.03)
    stream = [0.0] * 200 + [0.1] * 30 + [0.0] * 200  # touched, never pressed
    found = [segmenter.push(i * 0.001, (0.0, 0.0, 0.0), f) for i, f in enumerate(stream)]
    assert [f for f in found if f is not None] == [] and segmenter.rejected == 1
