"""palpd serve: the daemon (systemd runs this). Config errors exit 78 with one line.

With no arguments it runs the embedded simulated bench with the shipped paper scene,
its bus on loopback and the live view at http://127.0.0.1:8080/.
"""
from __future__ import annotations

import os

from palpd.errors import ConfigError, UsageError

LOG_LEVELS = ("debug", "info", "warning", "error")


def add_parser(subparsers):
    serve = subparsers.add_parser("serve", help="run the daemon: bus, commands, recorder, scans, live view")
    serve.add_argument("--config", metavar="FILE", help="settings (TOML); default: built-in, as `palpd files palpd.toml`")
    serve.add_argument("--scene", metavar="FILE|NAME",
                       help="scene of the simulated bench, a file or a shipped name (default: daemon.scene, else paper)")
    serve.add_argument("--log-level", choices=LOG_LEVELS, help="default: daemon.log_level (info)")
    return serve


def run(args) -> int:
    from palpd import __version__
    from palpd.config import load_settings
    from palpd.daemon.logs import setup_logging

    settings = load_settings(args.config)
    if settings.palpation.mode != "discrete":
        from palpd.errors import ConfigError

        raise ConfigError(f"palpation.mode = {settings.palpation.mode!r}: the daemon palpates discretely for now "
                          "(sliding runs in palpd scan and palpd bench tradeoff)")
    scene, scene_path = _scene(settings, args.scene)
    log = setup_logging(args.log_level or settings.daemon.log_level).getChild("daemon")

    def announce() -> None:  # once every endpoint is bound: a refusal before that stays one line
        log.info("palpd %s: config %s", __version__, args.config or "built-in defaults (no --config)")
        overrides = sorted(name for name in os.environ if name.startswith("PALPD_") and "__" in name)
        if overrides:
            log.info("environment overrides: %s", ", ".join(overrides))
        log.info("bench: simulated (robot %s, sensor %s), scene %r from %s, %s", settings.robot.url,
                 settings.sensor.backend, scene.name, scene_path,
                 "on the wall clock" if settings.daemon.realtime else "in virtual time")

    return _serve(settings, scene, announce)


def _scene(settings, requested: str | None):
    """The simulated bench's scene: --scene, else daemon.scene, else the shipped paper scene."""
    from drivers.errors import DriverError
    from drivers.sim.scene import load_scene
    from palpd.shipped import DEFAULT_SCENE, resolve_scene

    if not settings.robot.url.startswith("sim"):
        raise ConfigError(f"robot.url {settings.robot.url!r}: only the simulated bench (sim://) is available yet")
    try:
        path = resolve_scene(requested or settings.daemon.scene or DEFAULT_SCENE)
        return load_scene(path), path
    except (DriverError, UsageError) as exc:
        raise ConfigError(f"{'--scene' if requested else 'daemon.scene'}: {exc}") from None


def _serve(settings, scene, announce) -> int:
    from palpd.control.remote import open_servo_bench
    from palpd.daemon.supervisor import Supervisor

    def reopen_bench():
        return open_servo_bench(settings, scene, seed=settings.scan.seed, realtime=settings.daemon.realtime)

    bench = reopen_bench()
    try:
        supervisor = Supervisor(settings, bench, reopen_bench)
        supervisor.open(announce)
        return supervisor.serve()
    finally:
        bench.servo.close()  # idempotent: a clean shut-down has closed it already
        if "supervisor" in locals():
            supervisor.bench.servo.close()  # the one reset started, if the first was lost
