"""Only what pyproject.toml cannot say: config/ and systemd/ ship inside the wheel as the package data
`palpd.share` and `palpd.share.systemd` (read with importlib.resources), while staying where they are in the
repository, where the docs, the tests and everyone adding a scene expect them. Their data folders are listed
as packages too (palpd.share.scenes, ...): setuptools warns, once per folder and at length, about an
importable folder that is not, on every install."""
from pathlib import Path

from setuptools import find_packages, setup

SHARED = {"palpd.share": "config", "palpd.share.systemd": "systemd"}


def data_folders(package: str, folder: str) -> list[str]:
    """The folders under `folder` as the packages they import as (config/scenes/maps: palpd.share.scenes.maps)."""
    root = Path(__file__).parent / folder
    return [".".join([package, *path.relative_to(root).parts]) for path in sorted(root.rglob("*"))
            if path.is_dir() and "__pycache__" not in path.parts]


setup(packages=find_packages(include=["palpd*", "drivers*"])
      + [name for package, folder in SHARED.items() for name in [package, *data_folders(package, folder)]],
      package_dir=SHARED)
