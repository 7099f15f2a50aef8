"""Only what pyproject.toml cannot say: config/ and systemd/ ship inside the wheel as the package data
`palpd.share` and `palpd.share.systemd` (read with importlib.resources), while staying where they are in the
repository, where the docs, the tests and everyone adding a scene expect them."""
from setuptools import find_packages, setup

SHARED = {"palpd.share": "config", "palpd.share.systemd": "systemd"}

setup(packages=find_packages(include=["palpd*", "drivers*"]) + list(SHARED), package_dir=SHARED)
