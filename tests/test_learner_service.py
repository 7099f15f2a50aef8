"""`palpd learner` as a real process on real ZeroMQ sockets (loopback, random ports)."""
import json
import math
import signal
import subprocess
import sys

import pytest
import zmq

from daemon_client import PORT_RANGE, free_loopback_ports

from conftest import ROOT
from palpd.bus.messages import Estimate, Palpation, Stiffness

TIMEOUT_MS = 10_000
STARTUP_MS = 30_000


@pytest.fixture
def ctx():
    context = zmq.Context()
    yield context
    context.destroy(linger=0)


def receive(sock, timeout_ms=TIMEOUT_MS):
    assert sock.poll(timeout_ms), "no message in time"
    return sock.recv_multipart()


def k_paper(xy):
    return 0.12 + 0.68 / (1.0 + (math.hypot(xy[0] - 7.5, xy[1] + 4.0) / 10.0) ** 10)


def send(bus, topic, msg):
    bus.send_multipart([topic, msg.model_dump_json().encode()])


def palpate(bus, i, xy):
    """What the daemon publishes for one palpation of the paper scene: over the lump (k ≥ 0.5 N/mm) the force
    limit comes first, a censored reading (k ≥ its bound) with no stiffness event; elsewhere a fit."""
    k = k_paper(xy)
    if k >= 0.5:
        send(bus, b"palpation", Palpation(seq=i, t=float(i), index=i, xy_mm=xy, target_xy_mm=xy, depth_mm=[],
                                          force_n=[], outcome="too_stiff", stiffness_bound_n_per_mm=0.5,
                                          rejected="force limit before a stiffness"))
        return
    send(bus, b"palpation", Palpation(seq=i, t=float(i), index=i, xy_mm=xy, target_xy_mm=xy, depth_mm=[0.0, 1.0],
                                      force_n=[0.0, k], outcome="fit"))  # its stiffness follows: no estimate yet
    send(bus, b"stiffness", Stiffness(seq=i, t=float(i), index=i, xy_mm=xy, stiffness_n_per_mm=k,
                                      stiffness_sd_n_per_mm=0.001))


def test_learner_process_turns_palpations_into_estimates_with_next_probe(ctx, tmp_path):
    bus = ctx.socket(zmq.XPUB)
    bus.setsockopt(zmq.LINGER, 0)
    events_port = bus.bind_to_random_port("tcp://127.0.0.1", *PORT_RANGE)
    (learner_port,) = free_loopback_ports(1)
    cfg = tmp_path / "palpd.toml"
    cfg.write_text(f'[bus]\nevents = "tcp://127.0.0.1:{events_port}"\n'
                   f'learner_events = "tcp://127.0.0.1:{learner_port}"\n[learner]\ngrid_points = 61\n')
    proc = subprocess.Popen([sys.executable, "-m", "palpd", "learner", "--config", str(cfg)], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        # the learner subscribes once its numerics are loaded: seconds on a busy machine
        assert {receive(bus, STARTUP_MS)[0] for _ in range(2)} == {b"\x01stiffness", b"\x01palpation"}
        estimates = ctx.socket(zmq.SUB)
        estimates.setsockopt(zmq.LINGER, 0)
        estimates.setsockopt(zmq.SUBSCRIBE, b"estimate")
        estimates.connect(f"tcp://127.0.0.1:{learner_port}")
        topic, body = receive(estimates)  # a late subscriber gets the latest estimate at once
        first = Estimate.model_validate_json(body)
        assert topic == b"estimate" and first.points == 0 and first.next_probe_mm is not None
        bus.send_multipart([b"stiffness", b'{"not": "a stiffness message"}'])  # refused, not fatal
        # valid JSON a hostile or broken publisher could send: a NaN position had left the learner unable to
        # update again; each is refused in one line and the scan below goes on
        for topic, body in ((b"stiffness", '"xy_mm": [NaN, 1.0], "stiffness_n_per_mm": 0.2'),
                            (b"stiffness", '"xy_mm": [1.0, 1.0], "stiffness_n_per_mm": -0.2'),
                            (b"stiffness", '"xy_mm": [1.0, 1.0], "stiffness_n_per_mm": 0.2, "stiffness_sd_n_per_mm": Infinity'),
                            (b"palpation", '"xy_mm": [0.0, 0.0], "target_xy_mm": [Infinity, 0.0], "depth_mm": [], '
                                           '"force_n": [], "outcome": "no_contact"')):
            bus.send_multipart([topic, f'{{"v": 1, "seq": 0, "t": 0.5, "index": 0, {body}}}'.encode()])
        xy, latest, bounds = first.next_probe_mm, first, 0
        for i in range(1, 31):
            palpate(bus, i, xy)
            bounds += k_paper(xy) >= 0.5
            latest = Estimate.model_validate_json(receive(estimates)[1])
            assert latest.points == i and latest.seq > first.seq and latest.t == float(i)
            if latest.next_probe_mm is None:
                break
            xy = latest.next_probe_mm
        assert bounds >= 1 and not estimates.poll(200)  # one estimate per palpation, fit or bound
        assert len(latest.lumps) == 1  # the lump's only evidence that it is stiff: the bounds
        assert math.dist(latest.lumps[0].center_mm, (7.5, -4.0)) < 3.0
        assert latest.ambiguous_area_mm2 is not None
        assert latest.model.chosen == "circles:1" and latest.model.weight >= 0.9
    finally:
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert "stiffness message" in out and "Traceback" not in err
    assert "xy_mm" in out and "stiffness_n_per_mm" in out and "stiffness_sd_n_per_mm" in out and "target_xy_mm" in out


def test_learner_with_a_bad_endpoint_says_so_in_one_line(tmp_path):
    cfg = tmp_path / "palpd.toml"
    cfg.write_text('[bus]\nlearner_events = "nonsense://x"\n')
    result = subprocess.run([sys.executable, "-m", "palpd", "learner", "--config", str(cfg)], cwd=ROOT,
                            capture_output=True, text=True, timeout=30)
    assert result.returncode != 0 and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "nonsense://x" in result.stderr
