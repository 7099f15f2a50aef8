"""CURVE on the bus: strangers get nothing, observers read and may stop the arm but not command it; key hygiene."""
import json
import os
import stat
import subprocess
import sys
import time

import pytest
import zmq
import zmq.auth

from conftest import assert_one_line_error
from daemon_client import PORT_RANGE, Daemon, free_loopback_ports, receive
from palpd.bus.messages import Stiffness


def keys(directory, name):
    public, secret = zmq.auth.create_certificates(directory, name)
    os.chmod(secret, 0o600)  # as `palpd keygen` writes it (pyzmq's own is 0644, which palpd refuses)
    return zmq.auth.load_certificate(secret)


def client_keys(pair, server_public):
    return {"curve_publickey": pair[0], "curve_secretkey": pair[1], "curve_serverkey": server_public}


def test_unknown_key_gets_nothing_and_an_observer_cannot_start_a_scan(tmp_path, run_cli):
    for group in ("server", "operators", "observers", "strangers"):
        (tmp_path / group).mkdir()
    server_public, _ = keys(tmp_path / "server", "palpd")
    operator, observer, stranger = (keys(tmp_path / g, n) for g, n in
                                    (("operators", "op"), ("observers", "obs"), ("strangers", "x")))
    # The published halves go into the daemon's lists (zmq.auth reads *.key files).
    daemon = Daemon(tmp_path, env={"PALPD_BUS__CURVE_SECRET_KEY": str(tmp_path / "server" / "palpd.key_secret"),
                                   "PALPD_BUS__OPERATOR_KEYS": str(tmp_path / "operators"),
                                   "PALPD_BUS__OBSERVER_KEYS": str(tmp_path / "observers")})
    (tmp_path / "secrets").mkdir()
    for group in ("operators", "observers", "strangers"):  # clients keep their secrets out of the daemon's lists
        for secret in (tmp_path / group).glob("*.key_secret"):
            secret.rename(tmp_path / "secrets" / secret.name)
    try:
        daemon.start()
        as_operator = daemon.dealer(client_keys(operator, server_public))
        # the daemon's start-up (a servo process spawned, the bus bound) took over 20 s once on a busy host
        assert daemon.call("status", socket=as_operator, timeout_s=60.0)["state"] == "ready"
        as_observer = daemon.dealer(client_keys(observer, server_public))
        assert daemon.call("status", socket=as_observer)["ok"]
        refused = daemon.call("scan.start", {"max_palpations": 4}, socket=as_observer)
        assert refused["ok"] is False and refused["error"]["code"] == "forbidden"
        assert daemon.call("status", socket=as_operator)["state"] == "ready"  # nothing started

        as_stranger = daemon.dealer(client_keys(stranger, server_public))
        stranger_events = daemon.subscriber(keys=client_keys(stranger, server_public))
        plain = daemon.dealer()  # no CURVE at all
        assert daemon.call("status", socket=as_stranger, timeout_s=1.0) is None
        assert daemon.call("status", socket=plain, timeout_s=0.5) is None
        observer_events = daemon.subscriber("status", keys=client_keys(observer, server_public))
        assert daemon.call("scan.start", {"strategy": "raster", "max_palpations": 4}, socket=as_operator)["ok"]
        assert receive(observer_events) is not None  # the observer hears the scan...
        assert receive(stranger_events, timeout_s=0.5) is None  # ...the stranger hears nothing
        # issue 50: an emergency stop is open to every authenticated client; restarting the arm is not
        stopped = daemon.call("estop", socket=as_observer)
        assert stopped["ok"] and stopped["estop"], stopped
        give_up = time.monotonic() + 20.0
        while daemon.call("status", socket=as_observer)["state"] != "fault":
            assert time.monotonic() < give_up, "the observer's estop did not stop the scan"
            time.sleep(0.05)

        def palpctl(key_name, *args):
            return run_cli("--endpoint", daemon.commands, "--server-key", tmp_path / "server" / "palpd.key",
                           "--key", tmp_path / "secrets" / f"{key_name}.key_secret", "--timeout", "1", *args,
                           module="palpd.palpctl")

        assert palpctl("op", "estop").returncode == 0  # an operator's palpctl commands the robot
        refused = palpctl("obs", "reset")
        assert refused.returncode == 1 and "forbidden" in refused.stderr
        assert palpctl("op", "reset").returncode == 0
        assert palpctl("obs", "status").returncode == 0
        stranger_cli = palpctl("x", "status")
        assert stranger_cli.returncode == 1 and "keys right" in stranger_cli.stderr
    finally:
        daemon.close()


def test_keygen_writes_a_private_secret_into_a_directory_the_user_owns(tmp_path, run_cli):
    made = run_cli("keygen", "alice", env=dict(os.environ, XDG_CONFIG_HOME=str(tmp_path / "cfg")))
    assert made.returncode == 0, made.stderr
    keys = tmp_path / "cfg" / "palpd" / "keys"  # the default: the user's own config directory
    assert stat.S_IMODE(keys.stat().st_mode) == 0o700
    assert stat.S_IMODE((keys / "alice.key_secret").stat().st_mode) == 0o600
    assert stat.S_IMODE((keys / "alice.key").stat().st_mode) == 0o644  # the half to share
    again = run_cli("keygen", "alice", "--dir", keys)
    assert_one_line_error(again, "alice.key_secret exists")
    shared = tmp_path / "shared"
    shared.mkdir(mode=0o777)
    shared.chmod(0o777)
    assert_one_line_error(run_cli("keygen", "bob", "--dir", shared), str(shared), "chmod o-w")
    assert not list(shared.iterdir())


@pytest.fixture
def curve_config(tmp_path):
    """A daemon environment with CURVE keys laid out as the README's recipe does; yields (env, paths)."""
    (tmp_path / "server").mkdir(mode=0o700)
    (tmp_path / "operators").mkdir()
    keys(tmp_path / "server", "palpd")
    keys(tmp_path / "server", "alice")
    (tmp_path / "server" / "alice.key").rename(tmp_path / "operators" / "alice.key")
    env = Daemon(tmp_path).env | {"PALPD_BUS__CURVE_SECRET_KEY": str(tmp_path / "server" / "palpd.key_secret"),
                                  "PALPD_BUS__OPERATOR_KEYS": str(tmp_path / "operators")}
    return env, tmp_path


@pytest.mark.parametrize("spoil, fragments", [
    (lambda p: (p / "server" / "palpd.key_secret").chmod(0o644), ["palpd.key_secret", "mode 0644", "chmod 600"]),
    (lambda p: (p / "operators").chmod(0o777), ["operators", "writable by others", "chmod o-w"]),
    (lambda p: (p / "operators" / "alice.key").chmod(0o666), ["alice.key", "chmod o-w"]),
    (lambda p: (p / "server" / "alice.key_secret").rename(p / "operators" / "alice.key_secret"),
     ["alice.key_secret", "client's secret key", "move it"]),
])
def test_the_daemon_refuses_key_files_others_could_read_or_change(curve_config, run_cli, spoil, fragments):
    env, paths = curve_config
    spoil(paths)
    result = run_cli("serve", env=env)
    assert_one_line_error(result, *fragments)
    assert result.returncode == 78


def test_the_learner_refuses_a_non_loopback_endpoint_without_curve_and_serves_one_with_it(curve_config, run_cli):
    env, paths = curve_config
    bare = {k: v for k, v in env.items() if not k.startswith("PALPD_BUS__")}
    refused = run_cli("learner", env=bare | {"PALPD_BUS__LEARNER_EVENTS": "tcp://0.0.0.0:5999"})
    assert_one_line_error(refused, "bus.learner_events", "tcp://0.0.0.0:5999", "CURVE")
    assert refused.returncode == 78
    spoiled = (paths / "server" / "palpd.key_secret")
    spoiled.chmod(0o640)
    assert_one_line_error(run_cli("learner", env=env), "chmod 600")
    spoiled.chmod(0o600)


def test_the_learner_over_curve_hears_the_daemon_and_answers_only_known_keys(curve_config):
    env, paths = curve_config
    server_public, server_secret = zmq.auth.load_certificate(str(paths / "server" / "palpd.key_secret"))
    alice = zmq.auth.load_certificate(str(paths / "server" / "alice.key_secret"))
    learner_port = free_loopback_ports(1)[0]
    context = zmq.Context()
    bus = context.socket(zmq.XPUB)  # stands in for the daemon's event socket, a CURVE server with its keys
    bus.curve_secretkey, bus.curve_publickey, bus.curve_server = server_secret, server_public, True
    bus.setsockopt(zmq.LINGER, 0)
    port = bus.bind_to_random_port("tcp://127.0.0.1", *PORT_RANGE)
    learner = subprocess.Popen([sys.executable, "-m", "palpd", "learner"], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True,
                               env=env | {"PALPD_BUS__EVENTS": f"tcp://127.0.0.1:{port}",
                                          "PALPD_BUS__LEARNER_EVENTS": f"tcp://127.0.0.1:{learner_port}",
                                          "PALPD_LEARNER__GRID_POINTS": "31"})
    try:
        heard = {bus.recv() for _ in range(2) if bus.poll(20_000)}
        assert heard == {b"\x01stiffness", b"\x01palpation"}  # the learner subscribed through CURVE
        as_alice = context.socket(zmq.SUB)
        for option, value in client_keys(alice, server_public).items():
            setattr(as_alice, option, value)
        stranger = context.socket(zmq.SUB)
        for sub in (as_alice, stranger):
            sub.setsockopt(zmq.LINGER, 0)
            sub.subscribe(b"estimate")
            sub.connect(f"tcp://127.0.0.1:{learner_port}")
        assert as_alice.poll(20_000), "the operator got no estimate"
        assert as_alice.recv_multipart()[0] == b"estimate"
        bus.send_multipart([b"stiffness", Stiffness(seq=0, t=1.0, index=0, xy_mm=(0.0, 0.0),
                                                    stiffness_n_per_mm=0.5).model_dump_json().encode()])
        topic, body = as_alice.recv_multipart() if as_alice.poll(20_000) else (None, None)
        assert topic == b"estimate" and json.loads(body)["points"] == 1
        assert not stranger.poll(500)  # no keys, no estimates
    finally:
        learner.terminate()
        learner.communicate(timeout=10)
        context.destroy(linger=0)


def test_palpctl_refuses_a_secret_key_others_can_read(curve_config, run_cli):
    _, paths = curve_config
    secret = paths / "server" / "alice.key_secret"
    secret.chmod(0o644)
    result = run_cli("--endpoint", "tcp://127.0.0.1:1", "--server-key", paths / "server" / "palpd.key",
                     "--key", secret, "status", module="palpd.palpctl")
    assert_one_line_error(result, str(secret), "chmod 600")


@pytest.mark.parametrize("token, fragment", [("", "needs daemon.http_token"), ("short", "at least 16")])
def test_a_live_view_on_the_network_needs_a_long_token(tmp_path, run_cli, token, fragment):
    env = Daemon(tmp_path).env | {"PALPD_DAEMON__HTTP": "0.0.0.0:0", "PALPD_DAEMON__HTTP_TOKEN": token}
    result = run_cli("serve", env=env)
    assert_one_line_error(result, fragment)
    assert result.returncode == 78
