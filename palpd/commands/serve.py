"""palpd serve: the daemon (systemd runs this). Config errors exit 78 with one line."""
from __future__ import annotations

from palpd.errors import ConfigError


def add_parser(subparsers):
    serve = subparsers.add_parser("serve", help="run the daemon: bus, commands, recorder, scans")
    serve.add_argument("--config", metavar="FILE", help="settings (TOML); default: built-in, as config/palpd.toml")
    serve.add_argument("--scene", metavar="FILE", help="scene of the simulated bench (overrides daemon.scene)")
    return serve


def run(args) -> int:
    from drivers.errors import DriverError
    from drivers.sim.scene import load_scene
    from palpd.control.remote import open_servo_bench
    from palpd.config import load_settings
    from palpd.daemon.supervisor import Supervisor

    settings = load_settings(args.config)
    scene_path = args.scene or settings.daemon.scene
    if not settings.robot.url.startswith("sim"):
        raise ConfigError(f"robot.url {settings.robot.url!r}: only the simulated bench (sim://) is available yet")
    if not scene_path:
        raise ConfigError("daemon.scene: the simulated bench needs a scene file (set daemon.scene or --scene)")
    try:
        scene = load_scene(scene_path)
    except DriverError as exc:
        raise ConfigError(str(exc)) from None
    def reopen_bench():
        return open_servo_bench(settings, scene, seed=settings.scan.seed, realtime=settings.daemon.realtime)

    bench = reopen_bench()
    try:
        supervisor = Supervisor(settings, bench, reopen_bench)
        supervisor.open()
        return supervisor.serve()
    finally:
        bench.servo.close()  # idempotent: a clean shut-down has closed it already
        if "supervisor" in locals():
            supervisor.bench.servo.close()  # the one reset started, if the first was lost
