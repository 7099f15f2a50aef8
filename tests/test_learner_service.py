"""`palpd learner` as a real process on real ZeroMQ sockets (loopback, random ports)."""
import json
import math
import signal
import subprocess
import sys

import pytest
import zmq

from daemon_client import free_loopback_ports

from conftest import ROOT
from palpd.bus.messages import Estimate, Stiffness

TIMEOUT_MS = 10_000


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


def test_learner_process_turns_stiffness_into_estimates_with_next_probe(ctx, tmp_path):
    bus = ctx.socket(zmq.XPUB)
    bus.setsockopt(zmq.LINGER, 0)
    events_port = bus.bind_to_random_port("tcp://127.0.0.1")
    (learner_port,) = free_loopback_ports(1)
    cfg = tmp_path / "palpd.toml"
    cfg.write_text(f'[bus]\nevents = "tcp://127.0.0.1:{events_port}"\n'
                   f'learner_events = "tcp://127.0.0.1:{learner_port}"\n[learner]\ngrid_points = 61\n')
    proc = subprocess.Popen([sys.executable, "-m", "palpd", "learner", "--config", str(cfg)], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert receive(bus)[0] == b"\x01stiffness"  # the learner subscribed to stiffness only
        estimates = ctx.socket(zmq.SUB)
        estimates.setsockopt(zmq.LINGER, 0)
        estimates.setsockopt(zmq.SUBSCRIBE, b"estimate")
        estimates.connect(f"tcp://127.0.0.1:{learner_port}")
        topic, body = receive(estimates)  # a late subscriber gets the latest estimate at once
        first = Estimate.model_validate_json(body)
        assert topic == b"estimate" and first.points == 0 and first.next_probe_mm is not None
        bus.send_multipart([b"stiffness", b'{"not": "a stiffness message"}'])  # refused, not fatal
        xy, latest = first.next_probe_mm, first
        for i in range(1, 31):
            msg = Stiffness(seq=i, t=float(i), index=i, xy_mm=xy, stiffness_n_per_mm=k_paper(xy),
                            stiffness_sd_n_per_mm=0.001)
            bus.send_multipart([b"stiffness", msg.model_dump_json().encode()])
            latest = Estimate.model_validate_json(receive(estimates)[1])
            assert latest.points == i and latest.seq > first.seq and latest.t == float(i)
            if latest.next_probe_mm is None:
                break
            xy = latest.next_probe_mm
        assert len(latest.lumps) == 1
        assert math.dist(latest.lumps[0].center_mm, (7.5, -4.0)) < 3.0
        assert latest.ambiguous_area_mm2 is not None
        assert latest.model.chosen == "circles:1" and latest.model.weight >= 0.9
    finally:
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert "stiffness message" in out and "Traceback" not in err


def test_learner_with_a_bad_endpoint_says_so_in_one_line(tmp_path):
    cfg = tmp_path / "palpd.toml"
    cfg.write_text('[bus]\nlearner_events = "nonsense://x"\n')
    result = subprocess.run([sys.executable, "-m", "palpd", "learner", "--config", str(cfg)], cwd=ROOT,
                            capture_output=True, text=True, timeout=30)
    assert result.returncode != 0 and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "nonsense://x" in result.stderr
