"""palpd learner: the online learner as its own process on the bus."""
from __future__ import annotations


def add_parser(subparsers):
    learner = subparsers.add_parser("learner", help="run the online learner as its own process (ZeroMQ)")
    learner.add_argument("--config", metavar="FILE", help="settings (TOML); bus endpoints and learner section")
    return learner


def run(args) -> int:
    import zmq

    from palpd.bus.security import Security
    from palpd.config import load_settings
    from palpd.errors import ConfigError

    settings = load_settings(args.config)  # checked before the learner's numerics are imported
    security = Security.from_settings(settings.bus, ("learner_events",))  # non-loopback needs CURVE
    from palpd.learner.service import run_service

    security.start(zmq.Context.instance())
    try:
        return run_service(settings, security)
    except zmq.ZMQError as exc:
        raise ConfigError(f"bus: cannot use {settings.bus.events} / {settings.bus.learner_events}: {exc}") from None
    finally:
        security.stop()
