"""The service as a user meets it: schemas every reply keeps, a late subscriber's status, the Python client and
the scripting tutorial's client example, palpctl's edges, the live page in a real browser and the Foxglove stream.

One daemon (virtual time) serves the whole module; each test leaves it ready.
"""
import json
import re
import subprocess
import sys
import time

import jsonschema
import pytest

from browser import CHROMIUM, HeadlessChromium
from conftest import ROOT
from daemon_client import Daemon, free_loopback_ports, receive
from palpd.bus.messages import Estimate, Status
from palpd.client import Client, CommandRefused


@pytest.fixture(scope="module")
def daemon(tmp_path_factory):
    (foxglove_port,) = free_loopback_ports(1)
    d = Daemon(tmp_path_factory.mktemp("service"), env={"PALPD_DAEMON__FOXGLOVE": f"127.0.0.1:{foxglove_port}"})
    d.foxglove = f"ws://127.0.0.1:{foxglove_port}"
    d.start().wait_for(lambda s: s["state"] == "ready", what="ready")
    yield d
    d.close()


@pytest.fixture(scope="module")
def schemas():
    """What `palpd schema` publishes, read as a user would."""
    result = subprocess.run([sys.executable, "-m", "palpd", "schema"], capture_output=True, text=True, check=True)
    return json.loads(result.stdout)


def client_for(daemon, **options) -> Client:
    return Client(daemon.commands, daemon.events, **options)


def validate(schemas, name: str, body: dict) -> None:
    jsonschema.Draft202012Validator(schemas[name]).validate(body)


def test_every_published_schema_is_a_titled_described_draft_2020_12_schema_with_an_id(schemas):
    assert {f"reply.{c}" for c in ("status", "scan.start", "scan.stop", "estop", "reset", "estimate.get",
                                   "probe.at", "bias")} <= set(schemas)
    for name, schema in schemas.items():
        jsonschema.Draft202012Validator.check_schema(schema)
        assert schema["$schema"].endswith("2020-12/schema") and schema["$id"].endswith(f":{name}"), name
        assert schema["title"] and schema["description"], name


def test_a_late_subscriber_gets_the_status_within_a_second_and_the_reply_validates(daemon, schemas):
    subscriber = daemon.subscriber("status")
    joined = time.monotonic()
    topic, event = receive(subscriber, timeout_s=3.0)
    assert topic == "status" and time.monotonic() - joined < 1.0
    Status.model_validate(event)
    reply = daemon.call("status")
    validate(schemas, "reply.status", reply)
    validate(schemas, "status", {k: v for k, v in reply.items() if k not in ("id", "ok")})
    assert reply["seq"] >= event["seq"] and reply["state"] == "ready"


def test_the_client_scans_and_every_reply_and_event_keeps_its_schema(daemon, schemas, tmp_path):
    with client_for(daemon) as client:
        seen = []
        with client._subscription() as raw:
            ended = client.scan("active", max_palpations=14, wait=True, wait_timeout_s=120)
            while raw.poll(0):
                topic, payload = raw.recv_multipart()
                seen.append((topic.decode(), json.loads(payload)))
        assert ended.state == "ready" and 10 < ended.palpations <= 14  # the learner may decide before the budget
        for topic, payload in seen:
            validate(schemas, topic, payload)
        reply = client.estimate()
        assert reply.estimate.points == sum(p.stiffness_n_per_mm is not None for p in reply.probes) > 10
        assert [p.index for p in reply.probes] == list(range(ended.palpations)) and reply.map is not None
        raw_replies = {cmd: daemon.call(cmd, args) for cmd, args in
                       [("estimate.get", {}), ("status", {}), ("bias", {})]}
        daemon.wait_for(lambda s: s["state"] == "ready", what="tare done")
        raw_replies["estop"] = daemon.call("estop")
        raw_replies["reset"] = daemon.call("reset")
        for cmd, body in raw_replies.items():
            assert body["ok"], body
            validate(schemas, f"reply.{cmd}", body)
        with pytest.raises(CommandRefused) as refused:
            client.call("scan.stop")  # not scanning
        assert refused.value.code == "invalid_state"
        typed = next(client.events("status", timeout_s=3.0))
        assert isinstance(typed, Status) and typed.state == "ready"


def tutorial_client_example() -> str:
    """The scripting tutorial's client of a running daemon: the Python inside its `python - <<'PY'` block."""
    text = (ROOT / "docs" / "tutorials" / "scripting.md").read_text()
    (code,) = re.findall(r"python - <<'PY'\n(.*?)^PY$", text, re.S | re.M)
    return code


def test_the_scripting_tutorials_client_example_runs_against_a_daemon(daemon, tmp_path):
    (tmp_path / "client.py").write_text(tutorial_client_example())
    ran = subprocess.run([sys.executable, "client.py"], capture_output=True, text=True, env=daemon.env,
                         cwd=tmp_path, timeout=180)
    assert ran.returncode == 0, ran.stderr
    assert re.search(r"\(\s*-?\d+\.\d+, -?\d+\.\d+\)", ran.stdout), ran.stdout  # a lump's centre


def test_palpctl_edges_never_show_a_traceback(daemon, tmp_path):
    base = [sys.executable, "-m", "palpd.palpctl", "--endpoint", daemon.commands, "--events", daemon.events]
    help_text = subprocess.run([*base, "probe", "--help"], capture_output=True, text=True, timeout=30)
    assert help_text.returncode == 0 and "X Y" in help_text.stdout and not help_text.stderr
    version = subprocess.run([*base, "--version"], capture_output=True, text=True, timeout=30)
    assert version.returncode == 0 and re.fullmatch(r"palpctl \d+\.\d+\.\d+\n", version.stdout)
    head = subprocess.Popen([*base, "estimate"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    head.stdout.close()  # `palpctl estimate | head`: the reader is gone before palpctl writes
    assert head.wait(timeout=30) == 141 and head.stderr.read() == b""
    head.stderr.close()
    plotted = subprocess.run([*base, "plot", str(tmp_path / "map.png")], capture_output=True, text=True, timeout=60)
    assert plotted.returncode == 0 and (tmp_path / "map.png").read_bytes().startswith(b"\x89PNG"), plotted.stderr


@pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed (.ci/run installs it with apt-get)")
def test_the_live_page_follows_a_running_scan_in_headless_chromium(daemon, tmp_path):
    from PIL import Image

    assert daemon.call("estop")["ok"]  # a fault, cleared by reset before the scan: not on the page during it
    daemon.wait_for(lambda s: s["state"] == "fault", what="fault")
    assert daemon.call("reset")["ok"]
    daemon.wait_for(lambda s: s["state"] == "ready", what="ready after the reset")
    assert daemon.call("scan.start", {"strategy": "active", "max_palpations": 18, "seed": 2})["ok"]
    browser = HeadlessChromium(daemon.http, tmp_path / "profile")
    try:
        browser.wait_for("document.getElementById('state').textContent === 'scanning'")
        assert browser.evaluate("document.getElementById('faults').innerText") == "none"
        assert browser.evaluate("document.getElementById('map').dataset.ticksX") == "-30,-20,-10,0,10,20,30"
        assert browser.evaluate("document.getElementById('map').dataset.ticksY") == "-30,-20,-10,0,10,20,30"
        browser.wait_for("document.getElementById('map').dataset.nextProbe === '1'")  # the learner's next probe
        first = int(browser.wait_for("+document.getElementById('map').dataset.probes >= 3 && "
                                     "+document.getElementById('map').dataset.probes"))
        later = int(browser.wait_for(f"+document.getElementById('map').dataset.probes > {first} && "
                                     f"+document.getElementById('map').dataset.probes"))
        assert later > first  # the page follows the scan as events arrive
        assert int(browser.evaluate("+document.getElementById('map').dataset.mapCells")) > 100
        shot = Image.open(browser.screenshot(tmp_path / "live.png")).convert("RGB")
        # the documented screenshot (docs/how-to/screenshot-live-view.md), while the scan runs: ?snapshot=1
        # keeps no stream open, so the virtual time budget runs out
        subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                        f"--user-data-dir={tmp_path / 'shot-profile'}", "--window-size=1100,820",
                        "--virtual-time-budget=3000", f"--screenshot={tmp_path / 'snapshot.png'}",
                        daemon.http + "?snapshot=1"], capture_output=True, timeout=60, check=True)
        daemon.wait_for(lambda s: s["state"] == "ready", what="scan end", timeout_s=120)
        final = daemon.call("status")
        text = browser.wait_for(f"document.getElementById('palpations').textContent === '{final['palpations']}' "
                                f"&& document.getElementById('state').textContent === 'ready' "
                                f"&& document.getElementById('lumps').innerText")
        assert re.search(r"lump 1: centre \(.+\) ± [\d.]+ mm, radius [\d.]+ ± [\d.]+ mm", text), text
        model = browser.evaluate("document.getElementById('model').textContent")
        assert re.fullmatch(r"(none|circles:\d|ellipse:\d|free-form) \(weight [\d.]+(, runner-up \S+)?\)", model), model
        assert int(browser.evaluate("+document.getElementById('map').dataset.lumps")) >= 1
    finally:
        browser.close()
    colours = shot.crop((20, 60, 620, 660)).getcolors(1 << 16)
    assert colours is not None and len(colours) > 50  # a drawn map, not a blank canvas
    snapshot = Image.open(tmp_path / "snapshot.png").convert("RGB").crop((20, 60, 620, 660)).getcolors(1 << 16)
    assert snapshot is not None and len(snapshot) > 50  # the documented screenshot, mid-scan: a drawn map


def test_the_foxglove_stream_advertises_every_topic_and_streams_status(daemon):
    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    with connect(daemon.foxglove, subprotocols=["foxglove.sdk.v1", "foxglove.websocket.v1"], open_timeout=10) as ws:
        channels = {}
        while "status" not in channels:
            message = json.loads(ws.recv(timeout=10))
            if message["op"] == "advertise":
                channels |= {c["topic"]: c for c in message["channels"]}
        assert set(channels) == {"status", "palpation", "stiffness", "estimate", "fault"}  # not samples: never sent
        assert channels["status"]["encoding"] == "json" and json.loads(channels["status"]["schema"])["title"]
        ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": channels["status"]["id"]}]}))
        while isinstance(frame := ws.recv(timeout=5), str):
            pass
        assert frame[0] == 1 and int.from_bytes(frame[1:5], "little") == 7
        Status.model_validate_json(frame[13:])
    with pytest.raises(InvalidStatus, match="400"):  # as docs/how-to/foxglove.md says: the SDK's subprotocol only
        connect(daemon.foxglove, subprotocols=["foxglove.websocket.v1"], open_timeout=10)
