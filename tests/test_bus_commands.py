"""Bad requests get error replies with a code and a message; the daemon never crashes or blocks."""
import json
import socket

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from daemon_client import Daemon
from palpd.bus.commands import CommandError, parse_args, parse_request
from palpd.bus.security import is_local_endpoint

JSON = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
                    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=10), inner, max_size=4),
                    max_leaves=12)
COMMANDS = st.sampled_from(["status", "scan.start", "scan.stop", "estop", "reset", "estimate.get", "probe.at",
                            "bias", "nope", ""])
REQUESTS = (st.binary(max_size=200)
            | JSON.map(lambda v: json.dumps(v).encode())
            | st.fixed_dictionaries({"id": st.integers() | st.text(max_size=8), "cmd": COMMANDS,
                                     "args": st.dictionaries(st.sampled_from(["strategy", "max_palpations", "seed",
                                                                              "xy_mm", "size_mm", "resume", "x"]),
                                                             JSON, max_size=3)}).map(lambda r: json.dumps(r).encode()))


@given(REQUESTS)
def test_parsing_never_raises_anything_but_a_command_error(raw):
    try:
        parse_args(parse_request(raw))
    except CommandError as exc:
        assert exc.code in ("bad_json", "bad_request", "unknown_command", "bad_args") and exc.message


def test_wrong_types_are_named():
    with pytest.raises(CommandError, match="max_palpations") as err:
        parse_args(parse_request(b'{"id": 1, "cmd": "scan.start", "args": {"max_palpations": "5"}}'))
    assert err.value.code == "bad_args"


@pytest.fixture(scope="module")
def daemon(tmp_path_factory):
    d = Daemon(tmp_path_factory.mktemp("fuzz")).start()
    try:  # closed even when it never became ready: no daemon outlives the module
        d.wait_for(lambda s: s["state"] == "ready", what="ready")
        yield d
    finally:
        d.close()


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(raw=REQUESTS)
def test_the_running_daemon_answers_every_request_and_stays_up(daemon, raw):
    dealer = daemon.__dict__.setdefault("fuzz_dealer", daemon.dealer())
    dealer.send(raw)
    assert dealer.poll(5000), f"no reply to {raw!r}"
    reply = json.loads(dealer.recv())
    assert reply["ok"] or (reply["error"]["code"] and reply["error"]["message"])
    if reply["ok"] and reply.get("session"):  # the fuzzer started a scan: stop it, let the next example run
        daemon.call("scan.stop")
    if not reply["ok"]:
        daemon.call("reset")  # leave fault for the next example (an invalid_state reply when not faulted)
    daemon.assert_alive()


def test_state_invalid_commands_are_refused_with_a_reason(daemon):
    daemon.call("reset")  # the fuzzer may have left a fault or a stopping scan behind
    daemon.wait_for(lambda s: s["state"] == "ready", what="ready")
    reply = daemon.call("reset")
    assert reply["ok"] is False and reply["error"]["code"] == "invalid_state"
    assert daemon.call("estop")["ok"]
    daemon.wait_for(lambda s: s["state"] == "fault", what="fault")
    refused = daemon.call("scan.start", {"max_palpations": 4})
    assert refused["error"]["code"] == "invalid_state" and "fault" in refused["error"]["message"]
    assert daemon.call("reset")["ok"]
    daemon.wait_for(lambda s: s["state"] == "ready", what="ready: reset brings the arm home first")
    for strategy in ("raster", "active"):
        outside = daemon.call("scan.start", {"strategy": strategy, "center_mm": [25.0, 0.0], "size_mm": [20.0, 20.0]})
        assert outside["error"]["code"] == "bad_args" and "leaves the tissue" in outside["error"]["message"]


@pytest.mark.parametrize("endpoint, local", [
    ("tcp://127.0.0.1:5", True), ("tcp://[::1]:5", True), ("tcp://localhost:5", True), ("ipc:///tmp/x", True),
    ("tcp://0.0.0.0:5", False), ("tcp://*:5", False), ("tcp://192.168.1.2:5", False), ("tcp://eth0:5", False),
    ("udp://127.0.0.1:5", False)])
def test_which_endpoints_count_as_local(endpoint, local):
    assert is_local_endpoint(endpoint) is local


def test_sd_notify_ready_status_watchdog_stopping(tmp_path):
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    listener.bind(str(tmp_path / "notify"))
    listener.settimeout(20)
    d = Daemon(tmp_path, env={"NOTIFY_SOCKET": str(tmp_path / "notify"), "WATCHDOG_USEC": "200000"}).start()
    try:
        messages = []
        while not any("WATCHDOG=1" in m for m in messages):
            messages.append(listener.recv(4096).decode())
        assert any("READY=1" in m and "STATUS=ready" in m for m in messages), messages
        d.signal()
        while "STOPPING=1" not in messages[-1]:
            messages.append(listener.recv(4096).decode())
        assert d.wait() == 0
    finally:
        d.close()
        listener.close()
