"""The servo loop in its own process: samples through shared memory, tasks and faults over the pipe."""
import os
import signal
import threading
import time

import numpy as np
import pytest

from drivers.sim.scene import Scene
from palpd.config import Settings
from palpd.control import process, remote
from palpd.control.remote import open_servo_bench
from palpd.control.ring import FLAG_MOTORS_ON, FLAG_TASK
from palpd.control.tasks import HoldAndCollect, MoveTo
from palpd.errors import ConfigError, ScanFault

PERIOD_S = 0.001


@pytest.fixture(scope="module")
def bench():
    """One servo process for the tests that leave it usable (start-up costs a Python and numpy)."""
    bench = open_servo_bench(Settings(), Scene(name="p", tissue={"stiffness_n_per_mm": 0.6}))
    yield bench
    bench.servo.close()


def test_the_loop_runs_in_another_process_and_every_tick_reaches_the_ring_in_order(bench):
    servo = bench.servo
    assert servo.pid != os.getpid() and servo.process.is_alive()
    since = servo.header()["written"]
    servo.start()
    servo.run(MoveTo((0.0, 0.0, 4.0), 80.0, 2000.0))
    hold = HoldAndCollect(300)
    servo.run(hold)
    assert len(hold.samples) == 300  # the finished task came back through the pipe
    samples, next_index, lost = servo.ring.read_new(since)
    assert lost == 0 and next_index == servo.header()["written"] == since + len(samples)
    assert len(samples) > 300
    np.testing.assert_allclose(np.diff(samples["t_s"]), PERIOD_S, atol=1e-9)  # virtual time: no gaps, 1 kHz
    assert (samples["flags"] & FLAG_MOTORS_ON).all() and (samples["flags"] & FLAG_TASK).all()
    np.testing.assert_allclose(samples["tip_mm"][-1], (0.0, 0.0, 4.0), atol=0.5)
    assert servo.last_tick.t_s == pytest.approx(samples["t_s"][-1])
    # robot time between tasks is the last tick's, however many idle heartbeats came since (it was the
    # virtual clock's, 1-2 ms on, once a beat came before the clock was read: a race on a busy machine)
    time.sleep(3 * process.IDLE_BEAT_S)
    assert bench.clock.now() == pytest.approx(samples["t_s"][-1])
    servo.stop()


def test_a_fault_in_the_loop_reaches_the_parent_latched_with_the_motors_off(bench):
    servo = bench.servo
    servo.start()
    servo.run(MoveTo((0.0, 0.0, 2.0), 80.0, 2000.0))
    with pytest.raises(ScanFault, match="indentation"):
        # 0.6 N/mm tissue: 4.75 mm deep (depth_mm and the margin: the surface guard) comes before the cap
        servo.run(MoveTo((0.0, 0.0, -15.0), 20.0, 2000.0))
    assert servo.fault.code == "indentation" and servo.fault.last_samples
    assert not servo.motors_on and servo.amplifiers_on is False  # the simulated amplifiers, not a flag of ours
    assert servo.max_contact_force_n <= Settings().safety.force_cap_n + 1.0
    with pytest.raises(ScanFault, match="reset first"):
        servo.run(MoveTo((0.0, 0.0, 5.0), 20.0, 2000.0))
    servo.reset()
    assert servo.fault is None
    servo.start()
    servo.run(MoveTo((0.0, 0.0, 6.0), 40.0, 2000.0))
    servo.stop()


def test_an_estop_from_the_parent_trips_the_loop_within_one_tick(bench):
    servo = bench.servo
    servo.start()
    failure = []
    mover = threading.Thread(target=lambda: _run_catching(servo, MoveTo((20.0, 20.0, 30.0), 2.0, 100.0), failure))
    before = servo.header()["written"]
    mover.start()
    while servo.header()["written"] < before + 200:  # well under way (a 2 mm/s move takes seconds)
        time.sleep(0.001)
    servo.request_estop()
    latest, _, _ = servo.ring.read_new(servo.header()["written"] - 1)
    mover.join(30)
    assert failure and "estop" in failure[0]
    # The tick in progress when the flag was set had checked already; the next one trips.
    assert servo.fault.code == "estop" and servo.fault.t_s <= latest["t_s"][0] + 2 * PERIOD_S + 1e-9
    assert not servo.motors_on and servo.amplifiers_on is False
    with pytest.raises(ScanFault):  # latched until reset: no motion until then
        servo.run(MoveTo((0.0, 0.0, 6.0), 40.0, 2000.0))
    servo.reset()
    servo.start()
    servo.run(MoveTo((0.0, 0.0, 6.0), 40.0, 2000.0))
    servo.stop()


def _run_catching(servo, task, failure: list) -> None:
    try:
        servo.run(task)
    except ScanFault as exc:
        failure.append(str(exc))


def test_quit_ends_the_child_cleanly_and_a_killed_child_is_a_clear_fault_not_a_hang():
    bench = open_servo_bench(Settings(), Scene(name="q"))
    servo = bench.servo
    servo.start()
    servo.run(MoveTo((0.0, 0.0, 6.0), 80.0, 2000.0))
    os.kill(servo.pid, signal.SIGKILL)
    started = time.monotonic()
    with pytest.raises(ScanFault, match="servo_lost: servo process"):
        servo.run(MoveTo((0.0, 0.0, 8.0), 80.0, 2000.0))
    assert time.monotonic() - started < 2.0 and servo.fault.code == "servo_lost"
    servo.stop()  # a dead child's motors are off already: no error on the way out
    servo.close()

    clean = open_servo_bench(Settings(), Scene(name="q"))
    clean.servo.close()
    assert clean.servo.process.exitcode == 0


def test_a_hung_child_is_noticed_by_its_missing_heartbeat(monkeypatch):
    monkeypatch.setattr(remote, "UNRESPONSIVE_S", 0.5)
    bench = open_servo_bench(Settings(), Scene(name="h"))
    servo = bench.servo
    try:
        servo.start()
        os.kill(servo.pid, signal.SIGSTOP)
        started = time.monotonic()
        with pytest.raises(ScanFault, match="no heartbeat"):
            servo.run(MoveTo((0.0, 0.0, 8.0), 80.0, 2000.0))
        assert time.monotonic() - started < 3.0
    finally:
        servo.close()
    assert not servo.process.is_alive()


def test_an_unsafe_configuration_is_refused_by_the_child_with_the_same_error():
    with pytest.raises(ConfigError, match="force_cap_n"):
        open_servo_bench(Settings().updated(safety={"force_cap_n": 100.0}), Scene(name="c"))


def test_a_fault_latched_between_tasks_is_seen_by_check_idle_and_a_dead_child_is_lost():
    """On the wall clock the idle loop keeps watching: a trip with nobody waiting on the pipe still shows."""
    bench = open_servo_bench(Settings(), Scene(name="p", tissue={"stiffness_n_per_mm": 0.6}), realtime=True)
    servo = bench.servo
    try:
        assert servo.check_idle() is None and not servo.lost
        servo.ring.set_estop(True)  # as the bridge's e-stop would, with no task running
        give_up = time.monotonic() + 5.0
        while servo.check_idle() is None and time.monotonic() < give_up:
            time.sleep(0.01)
        assert servo.fault is not None and servo.fault.code == "estop" and not servo.lost
        servo.reset()
        assert servo.check_idle() is None
        os.kill(servo.pid, signal.SIGKILL)
        servo.process.join(5.0)
        fault = servo.check_idle()
        assert fault.code == "servo_lost" and "exited" in fault.message and servo.lost
    finally:
        servo.close()


def _slow_lift_palpation():
    """A palpation whose lift to clearance lasts seconds of robot time (30 mm at 5 mm/s)."""
    from palpd.control.palpation import Palpation

    p = Settings().palpation.model_copy(update={"clearance_mm": 30.0, "approach_speed_mm_s": 5.0})
    return Palpation((0.0, 0.0), p)


def test_a_begun_palpation_comes_back_once_its_record_is_final_and_ends_while_the_parent_works(bench):
    servo = bench.servo
    servo.start()
    palpation = _slow_lift_palpation()
    servo.begin(palpation)
    assert palpation.settled and not palpation.done  # out of the press, still lifting in the servo process
    record = palpation.finish()  # fitted here, as a scan does, while the servo process lifts
    assert record.contact and record.t_end_s == 0.0
    depth, force, unload = list(record.depth_mm), list(record.force_n), list(record.unload_force_n)
    settled_at, give_up = servo.last_tick.t_s, time.monotonic() + 30.0
    while servo.header()["now_s"] < settled_at + 0.2 and time.monotonic() < give_up:
        time.sleep(0.001)
    assert servo.header()["now_s"] >= settled_at + 0.2  # the lift goes on while we work
    servo.settle()  # its end: what the lift added to the record, nothing else of it changed
    assert palpation.done and record.t_end_s > servo.last_tick.t_s - 0.01
    assert (record.depth_mm, record.force_n, record.unload_force_n) == (depth, force, unload)
    assert servo.last_tick.tip_mm[2] == pytest.approx(30.0, abs=0.5)
    servo.stop()


def test_a_fault_while_a_begun_palpation_lifts_is_raised_by_settle_and_latched(bench):
    servo = bench.servo
    servo.start()
    palpation = _slow_lift_palpation()
    servo.begin(palpation)
    servo.request_estop()  # seconds of lift still to go
    with pytest.raises(ScanFault, match="estop"):
        servo.settle()
    assert servo.fault.code == "estop" and not servo.motors_on and not palpation.done
    assert palpation.finish().contact  # the record handed back stands
    servo.settle()  # raised once
    servo.reset()
    servo.settle()
    servo.start()
    servo.run(MoveTo((0.0, 0.0, 6.0), 40.0, 2000.0))
    servo.stop()


def test_in_process_a_fault_after_a_begun_palpation_settled_is_raised_by_settle_too():
    from palpd.bench import open_simulated_bench

    servo = open_simulated_bench(Settings(), Scene(name="p", tissue={"stiffness_n_per_mm": 0.6})).servo
    servo.start()
    palpation = _slow_lift_palpation()
    servo.tick_hook = lambda tick: palpation.settled and servo.request_estop()
    servo.begin(palpation)  # runs to the fault here; raised where the servo process raises it
    assert servo.fault.code == "estop" and palpation.settled and not palpation.done
    with pytest.raises(ScanFault, match="estop"):
        servo.settle()
    servo.settle()
    servo.tick_hook = None
    servo.reset()
    servo.start()
    again = _slow_lift_palpation()
    servo.tick_hook = lambda tick: again.settled and servo.request_estop()
    servo.begin(again)  # the same fault again, not raised yet...
    servo.tick_hook = None
    servo.reset()  # ...is the latched fault a reset clears: nothing left to raise
    servo.settle()
    servo.start()
    servo.stop()
