"""Bad requests get error replies with a code and a message; the daemon never crashes or blocks."""
import json
import socket

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from daemon_client import Daemon
from palpd.bus.requests import CommandError, check_role, parse_args, read_header
from palpd.bus.security import LOCAL, OBSERVER, is_local_endpoint

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
# Raw JSON text with what json.dumps cannot or will not write: integers past CPython's 4300-digit limit, floats
# past float range, NaN, deep nesting, lone surrogates, odd Unicode, duplicate keys, invalid UTF-8.
HUGE_NUMBERS = st.sampled_from([b"9" * 4301, b"-" + b"1" * 5000, b"1e999", b"-1e400", b"1" * 39 + b".5e-400",
                                b"NaN", b"Infinity", b"-Infinity", b"18446744073709551617", b"1" * 41])
ODD_TEXT = (st.text(st.characters(codec="utf-8"), max_size=12).map(lambda t: json.dumps(t, ensure_ascii=False).encode())
            | st.sampled_from([b'"\\ud800"', b'"\\udfff\\ud800"', b'"\\u0000"', b'"\xef\xbf\xbf"',
                               b'"\xff\xfe"', b'"\xed\xa0\x80"', b'"\\"', b'"' + b"z" * 1500 + b'"']))
LEAVES = HUGE_NUMBERS | ODD_TEXT | st.sampled_from([b"null", b"true", b"0", b"-0.0", b"[]", b"{}"])
NESTED = st.integers(1, 30000).map(lambda n: b"[" * n + b"]" * n) | st.integers(1, 3000).map(
    lambda n: b'{"a":' * n + b"1" + b"}" * n)
VALUES = st.recursive(LEAVES | NESTED, lambda inner: st.lists(inner, max_size=3).map(lambda v: b"[" + b",".join(v) + b"]")
                      | st.lists(st.tuples(ODD_TEXT, inner), max_size=3).map(
                          lambda kv: b"{" + b",".join(k + b":" + v for k, v in kv) + b"}"), max_leaves=6)
HOSTILE = st.tuples(VALUES, COMMANDS.map(lambda c: json.dumps(c).encode()) | VALUES, VALUES, st.booleans()).map(
    lambda p: b'{"id":' + p[0] + b',"cmd":' + p[1] + b',"args":' + p[2] + (b',"cmd":"status"}' if p[3] else b"}"))


def parse(raw: bytes, role: str = LOCAL):
    """What the command server does with a request's body, step by step."""
    header = read_header(raw)
    check_role(header.cmd, role)
    return parse_args(header.cmd, header.body)


@given(REQUESTS | HOSTILE)
def test_parsing_never_raises_anything_but_a_command_error(raw):
    try:
        parse(raw)
    except CommandError as exc:
        assert exc.code in ("bad_json", "bad_request", "unknown_command", "bad_args") and exc.message


def test_wrong_types_are_named():
    with pytest.raises(CommandError, match="max_palpations") as err:
        parse(b'{"id": 1, "cmd": "scan.start", "args": {"max_palpations": "5"}}')
    assert err.value.code == "bad_args"


@pytest.mark.parametrize("raw, message", [
    (b'{"id": ' + b"7" * 5000 + b', "cmd": "status"}', "a number of 5000 characters"),
    (b'{"id": 1, "cmd": "status", "args": {"x": 1e999}}', "beyond float range"),
    (b'{"id": 1, "cmd": "status", "args": {"x": NaN}}', "NaN is not a JSON number"),
    (b'{"id": 1, "cmd": "status", "args": ' + b"[" * 20 + b"]" * 20 + b"}", "nested deeper than 16"),
    (b'{"id": 1, "cmd": "' + b"s" * 2000 + b'"}', "a string of 2000 bytes"),
    (b'{"id": 1, "cmd": "status", "cmd": "estop"}', "duplicate key 'cmd'"),
    (b'{"id": 1, "cmd": "status", "args": {"x": "\\\\ud800"}}', None),  # an escaped backslash: plain text
    (b'{"id": 1, "cmd": "st\\\\ud800atus"}', None),
    (b'{"id": 1, "cmd": "st\\ud800atus"}', "unpaired surrogate"),
    (b'{"id": 1, "cmd": "status", "pad": "' + b"x" * 70000 + b'"}', "at most 65536"),
])
def test_bounds_hold_before_the_parser_sees_the_request(raw, message):
    if message is None:
        with pytest.raises(CommandError) as error:
            parse(raw)
        assert "surrogate" not in error.value.message  # refused for its content, not its Unicode
        return
    with pytest.raises(CommandError, match=message):
        parse(raw)


def test_the_role_is_checked_before_the_arguments():
    garbage_args = b'{"id": "a", "cmd": "scan.start", "args": {"max_palpations": "many", "x": [[[]]]}}'
    with pytest.raises(CommandError) as error:
        parse(garbage_args, role=OBSERVER)
    assert error.value.code == "forbidden"
    assert parse(b'{"id": "a", "cmd": "status"}', role=OBSERVER) is not None


@pytest.fixture(scope="module")
def daemon(tmp_path_factory):
    d = Daemon(tmp_path_factory.mktemp("fuzz")).start()
    try:  # closed even when it never became ready: no daemon outlives the module
        d.wait_for(lambda s: s["state"] == "ready", what="ready")
        yield d
    finally:
        d.close()


def answer(dealer, frames: list[bytes], timeout_s: float = 5.0) -> dict:
    dealer.send_multipart(frames)
    assert dealer.poll(int(timeout_s * 1000)), f"no reply to {frames!r:.200}"
    return json.loads(dealer.recv_multipart()[-1])


FRAMES = (REQUESTS | HOSTILE | st.binary(max_size=300)).map(lambda raw: [raw]) | st.lists(
    REQUESTS | st.binary(max_size=20), min_size=2, max_size=4)  # a REQ's empty delimiter, or frames too many


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                 HealthCheck.too_slow, HealthCheck.data_too_large])
@given(frames=FRAMES)
def test_the_running_daemon_answers_every_request_and_stays_up(daemon, frames):
    """The real ROUTER socket of a running daemon, hypothesis-generated hostile requests: a reply to each."""
    dealer = daemon.__dict__.setdefault("fuzz_dealer", daemon.dealer())
    reply = answer(dealer, frames)
    assert reply["ok"] or (reply["error"]["code"] and reply["error"]["message"])
    assert reply["ok"] or reply["error"]["code"] != "internal", reply  # every problem has a proper name
    if reply["ok"] and reply.get("session"):  # the fuzzer started a scan: stop it, let the next example run
        daemon.call("scan.stop")
    if reply["ok"] and (reply.get("estop") or reply.get("accepted")):
        daemon.call("reset")
    daemon.assert_alive()


def test_a_5000_digit_id_gets_an_error_reply_and_the_daemon_still_answers_status(daemon):
    dealer = daemon.dealer()
    reply = answer(dealer, [b'{"id": ' + b"9" * 5000 + b', "cmd": "status", "args": {}}'])
    assert reply == {"id": None, "ok": False,
                     "error": {"code": "bad_request", "message": "a number of 5000 characters; at most 40"}}
    assert answer(dealer, [b'{"id": "after", "cmd": "status"}'])["id"] == "after"


def test_oversize_frames_get_an_error_reply_and_giant_ones_cost_only_their_sender(daemon):
    dealer = daemon.dealer()
    big = b'{"id": "big", "cmd": "status", "args": {"pad": "' + b"x" * 1000 + b'"}}' + b" " * 200_000
    reply = answer(dealer, [big])
    assert reply["id"] is None and "at most 65536" in reply["error"]["message"]
    giant = daemon.dealer()
    giant.send(b" " * (2 << 20))  # beyond MAX_FRAME_BYTES: the transport drops the connection, unread
    assert daemon.call("status", socket=dealer)["ok"] and daemon.call("status")["ok"]
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
