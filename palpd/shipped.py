"""What palpd ships inside its package (importlib.resources): scenes, the default config, the Nano17
calibration file, the systemd unit and udev rule. In the repository these are config/ and systemd/;
setup.py maps them into the wheel as palpd.share, so an installed palpd works from any directory.

`--scene NAME` resolves here: an existing file wins, otherwise a shipped scene by name.
"""
from __future__ import annotations

import atexit
from contextlib import ExitStack
from importlib import resources
from pathlib import Path

from palpd.errors import ConfigError, UsageError

SCENE_SUFFIX = ".toml"
DEFAULT_SCENE = "paper"
_extracted = ExitStack()  # keeps files extracted from a zipped install alive until exit
atexit.register(_extracted.close)


def share_dir():
    return resources.files("palpd.share")


def _as_path(resource) -> Path:
    """A real file path for a shipped resource (a plain install already has one)."""
    return _extracted.enter_context(resources.as_file(resource))


def scene_names() -> list[str]:
    """The shipped scenes, by name (their file names without .toml), sorted."""
    scenes = share_dir() / "scenes"
    return sorted(p.name[:-len(SCENE_SUFFIX)] for p in scenes.iterdir() if p.name.endswith(SCENE_SUFFIX))


def shipped_scene(name: str) -> Path:
    return _as_path(share_dir() / "scenes" / f"{name}{SCENE_SUFFIX}")


def resolve_scene(name_or_path: str | Path) -> Path:
    """An existing file as given, else the shipped scene of that name (with or without .toml).

    A name that is neither is a configuration error (exit 78, as a bad scene file) listing the shipped scenes.
    """
    path = Path(name_or_path)
    if path.exists():
        return path
    name = path.name[:-len(SCENE_SUFFIX)] if path.name.endswith(SCENE_SUFFIX) else path.name
    if str(path.parent) == "." and name in scene_names():
        return shipped_scene(name)
    raise ConfigError(f"{name_or_path}: scene file not found, and no shipped scene has that name "
                     f"(shipped: {', '.join(scene_names())}; `palpd scenes` lists them)")


def load_scene_named(name_or_path: str | Path):
    """The scene of a file or a shipped name (drivers.sim.scene.Scene)."""
    from drivers.sim.scene import load_scene

    return load_scene(resolve_scene(name_or_path))


def default_config() -> Path:
    """The shipped palpd.toml: every setting with its built-in default."""
    return shipped_file("palpd.toml")


# `palpd files NAME` prints these: what an installer copies out of the package. Name -> (package, path).
FILES = {"palpd.toml": ("palpd.share", "palpd.toml"),
         "calibration/FT8577.cal": ("palpd.share", "calibration/FT8577.cal"),
         "systemd/palpd.service": ("palpd.share.systemd", "palpd.service"),
         "systemd/99-phantom-bridge.rules.in": ("palpd.share.systemd", "99-phantom-bridge.rules.in")}


def shipped_file(name: str) -> Path:
    if name not in FILES:
        raise UsageError(f"no shipped file {name!r}; choose from {', '.join(FILES)}")
    package, relative = FILES[name]
    return _as_path(resources.files(package).joinpath(*relative.split("/")))
