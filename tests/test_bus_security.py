"""CURVE on the bus: strangers get nothing, observers read but cannot command the robot."""
import zmq
import zmq.auth

from daemon_client import Daemon, receive


def keys(directory, name):
    public, secret = zmq.auth.create_certificates(directory, name)
    return zmq.auth.load_certificate(secret)


def client_keys(pair, server_public):
    return {"curve_publickey": pair[0], "curve_secretkey": pair[1], "curve_serverkey": server_public}


def test_unknown_key_gets_nothing_and_an_observer_cannot_start_a_scan(tmp_path):
    for group in ("server", "operators", "observers", "strangers"):
        (tmp_path / group).mkdir()
    server_public, _ = keys(tmp_path / "server", "palpd")
    operator, observer, stranger = (keys(tmp_path / g, n) for g, n in
                                    (("operators", "op"), ("observers", "obs"), ("strangers", "x")))
    # The published halves go into the daemon's lists (zmq.auth reads *.key files).
    daemon = Daemon(tmp_path, env={"PALPD_BUS__CURVE_SECRET_KEY": str(tmp_path / "server" / "palpd.key_secret"),
                                   "PALPD_BUS__OPERATOR_KEYS": str(tmp_path / "operators"),
                                   "PALPD_BUS__OBSERVER_KEYS": str(tmp_path / "observers")})
    for group in ("operators", "observers", "strangers"):
        for secret in (tmp_path / group).glob("*.key_secret"):
            secret.unlink()
    try:
        daemon.start()
        as_operator = daemon.dealer(client_keys(operator, server_public))
        assert daemon.call("status", socket=as_operator)["state"] == "ready"
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
        assert daemon.call("scan.start", {"max_palpations": 4}, socket=as_operator)["ok"]
        assert receive(observer_events) is not None  # the observer hears the scan...
        assert receive(stranger_events, timeout_s=0.5) is None  # ...the stranger hears nothing
    finally:
        daemon.close()
