"""CURVE on the bus: strangers get nothing, observers read but cannot command the robot."""
import zmq
import zmq.auth

from daemon_client import Daemon, receive


def keys(directory, name):
    public, secret = zmq.auth.create_certificates(directory, name)
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
