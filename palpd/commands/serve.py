"""palpd serve: the daemon (systemd runs this). Config and scene errors exit 78 with one line.

With no arguments it runs the embedded simulated bench with the shipped paper scene,
its bus on loopback and the live view at http://127.0.0.1:8080/. With robot.url and
sensor.backend naming real devices (usb://, serial://, socket://; netft://, nidaqmx://)
it drives them exactly as `palpd scan` does; a scene then only says where the tissue is.
"""
from __future__ import annotations

import os

from palpd.errors import ConfigError

LOG_LEVELS = ("debug", "info", "warning", "error")


def add_parser(subparsers):
    serve = subparsers.add_parser("serve", help="run the daemon: bus, commands, recorder, scans, live view")
    serve.add_argument("--config", metavar="FILE", help="settings (TOML); default: built-in, as `palpd files palpd.toml`")
    serve.add_argument("--scene", metavar="FILE|NAME",
                       help="scene of the simulated bench, a file or a shipped name (default: daemon.scene, else "
                            "paper); on hardware it only says where the tissue is (default: the config's [tissue])")
    serve.add_argument("--log-level", choices=LOG_LEVELS, help="default: daemon.log_level (info)")
    return serve


def run(args) -> int:
    from palpd import __version__
    from palpd.bench import check_reach
    from palpd.bus.security import Security
    from palpd.daemon.viewers import check_live_view
    from palpd.config import load_settings
    from palpd.daemon.logs import setup_logging

    settings = load_settings(args.config)
    scene, scene_path = _scene(settings, args.scene)
    check_reach(settings, scene)  # before anything binds or spawns: one line, exit 78
    security = Security.from_settings(settings.bus)  # CURVE for non-loopback endpoints, private key files
    if settings.daemon.http:
        check_live_view(settings.daemon.http, settings.daemon.http_token)  # a token for a non-loopback view
    log = setup_logging(args.log_level or settings.daemon.log_level).getChild("daemon")

    def announce() -> None:  # once every endpoint is bound: a refusal before that stays one line
        log.info("palpd %s: config %s", __version__, args.config or "built-in defaults (no --config)")
        overrides = sorted(name for name in os.environ if name.startswith("PALPD_") and "__" in name)
        if overrides:
            log.info("environment overrides: %s", ", ".join(overrides))
        log.info("bench: %s", _describe_bench(settings, scene, scene_path))

    _prepare_3d_tissue(settings, scene, log)
    return _serve(settings, scene, security, announce)


def _prepare_3d_tissue(settings, scene, log) -> None:
    """A simulated 3-D scene's force table, read from the cache or built (minutes, once per scene) before the
    servo process starts, with systemd told to wait meanwhile: Type=notify gives a start 90 s by default."""
    if scene is None or not scene.tissue.is_3d or not settings.robot.url.startswith("sim"):
        return
    import threading
    import time

    from drivers.sim.mechanics.table import cache_dir, cached_table
    from palpd.daemon.notify import Notifier

    notifier, done = Notifier(), threading.Event()

    def keep_extending() -> None:
        while True:
            notifier.notify(f"EXTEND_TIMEOUT_USEC={int(3 * TABLE_NOTIFY_S * 1e6)}",
                            "STATUS=building the 3-D tissue's force table (once per scene)")
            if done.wait(TABLE_NOTIFY_S):
                return

    extender = threading.Thread(target=keep_extending, name="palpd-table-notify", daemon=True)
    extender.start()
    started = time.monotonic()
    try:
        table = cached_table(scene)
    finally:
        done.set()
        extender.join()
        notifier.close()
    log.info("3-D tissue: force table %d x %d points x %d depths in %.1f s (cache %s)", len(table.xs),
             len(table.ys), len(table.depths_mm), time.monotonic() - started, cache_dir())


TABLE_NOTIFY_S = 10.0


def _scene(settings, requested: str | None):
    """(scene, path): --scene, else daemon.scene; for the simulated bench, else the shipped paper scene.
    On hardware a scene only says where the tissue is, and without one the config's [tissue] does."""
    from drivers.errors import DriverError
    from drivers.sim.scene import load_scene
    from palpd.shipped import DEFAULT_SCENE, resolve_scene

    name = requested or settings.daemon.scene
    if not name and not settings.robot.url.startswith("sim"):
        return None, None
    try:
        path = resolve_scene(name or DEFAULT_SCENE)
        return load_scene(path), path
    except (DriverError, ConfigError) as exc:
        raise ConfigError(f"{'--scene' if requested else 'daemon.scene'}: {exc}") from None


def _describe_bench(settings, scene, scene_path) -> str:
    if settings.robot.url.startswith("sim"):
        clock = "on the wall clock" if settings.daemon.realtime else "in virtual time"
        return (f"simulated (robot {settings.robot.url}, sensor {settings.sensor.backend}), scene {scene.name!r} "
                f"from {scene_path}, {clock}")
    where = f"scene {scene.name!r} from {scene_path}" if scene else "[tissue] of the config"
    return (f"robot {settings.robot.url}, force sensor {settings.sensor.backend}, tissue placed by {where}, "
            "on the wall clock")


def _serve(settings, scene, security, announce) -> int:
    from palpd.control.remote import open_servo_bench
    from palpd.daemon.supervisor import Supervisor

    def reopen_bench():
        return open_servo_bench(settings, scene, seed=settings.scan.seed, realtime=settings.daemon.realtime)

    bench = reopen_bench()
    try:
        supervisor = Supervisor(settings, bench, reopen_bench, security)
        supervisor.open(announce)
        return supervisor.serve()
    finally:
        bench.servo.close()  # idempotent: a clean shut-down has closed it already
        if "supervisor" in locals():
            supervisor.bench.servo.close()  # the one reset started, if the first was lost
