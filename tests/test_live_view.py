"""The live view's server and feed in this process (no daemon): the token's session cookie, current faults only.
The page itself, in a real browser, is tests/test_service_api.py's."""
import json
import urllib.error
import urllib.request

import pytest

from palpd.daemon.viewers import LiveView

TOKEN = "a-token-long-enough-to-be-hard-to-guess"


@pytest.fixture
def view(request):
    live = LiveView("127.0.0.1:0", getattr(request, "param", ""), (60.0, 60.0))
    yield live
    live.close()


def get(url: str, cookie: str | None = None, read: int = -1):
    request = urllib.request.Request(url, headers={"Cookie": cookie} if cookie else {})
    with urllib.request.urlopen(request, timeout=5) as answer:
        return answer.status, answer.headers, answer.read(read) if read >= 0 else answer.read()


@pytest.mark.parametrize("view", [TOKEN], indirect=True)
def test_the_page_loaded_with_the_token_lets_its_script_and_stream_in_by_a_session_cookie(view):
    """With daemon.http_token the page loaded, but its live.js (a script tag with no token) got 401: blank."""
    base = view.url
    with pytest.raises(urllib.error.HTTPError, match="401"):
        get(base + "live.js")
    status, headers, _ = get(f"{base}?token={TOKEN}")
    cookie = headers["Set-Cookie"]
    assert status == 200 and "HttpOnly" in cookie and "SameSite=Strict" in cookie
    session = cookie.split(";")[0]
    assert get(base + "live.js", session)[0] == 200
    status, _, first = get(base + "events", session, read=15)
    assert status == 200 and first.startswith(b"event: snapshot")
    with pytest.raises(urllib.error.HTTPError, match="401"):
        get(base + "live.js", "palpd_token=wrong")


def status(state: str, seq: int) -> dict:
    return {"v": 1, "seq": seq, "t": float(seq), "state": state, "message": "", "session": "s", "palpations": 0}


def test_a_fault_cleared_by_reset_leaves_the_faults_panel(view):
    """A fault cleared by `reset` stayed red in the panel while the next scan ran."""
    view.event("status", status("scanning", 0))
    view.event("fault", {"t": 1.0, "code": "estop", "message": "emergency stop requested"})
    view.event("status", status("scanning", 1))  # the heartbeat before the job has ended: the fault stands
    assert [f["code"] for f in view.state.snapshot()["faults"]] == ["estop"]
    view.event("status", status("fault", 2))
    assert [f["code"] for f in view.state.snapshot()["faults"]] == ["estop"]
    view.event("status", status("configure", 3))  # reset: bringing the arm home
    assert view.state.snapshot()["faults"] == []
    view.event("status", status("scanning", 4))
    assert view.state.snapshot()["faults"] == []


def test_only_the_learner_s_scans_name_a_next_probe_for_the_ring():
    """The live view drew the learner's next-probe ring during raster scans: the estimate named one there too."""
    from palpd.config import Settings
    from palpd.daemon.learning import make_estimator

    for strategy, named in (("active", True), ("raster", False), ("random", False)):
        scan = {"strategy": strategy, "size_mm": [60.0, 60.0], "center_mm": [0.0, 0.0], "max_palpations": 9, "seed": 0}
        estimator = make_estimator(Settings(), scan, (60.0, 60.0))
        assert (estimator.estimate()["next_probe_mm"] is not None) == named, strategy
