"""MkDocs hook: the reference pages, generated from the code at every build so they cannot drift.

- reference/palpd.md and reference/palpctl.md: every command and subcommand, from the argparse parsers;
- reference/settings.md: every setting, from the pydantic models in palpd.config (type, default, bounds, unit,
  the environment variable), described by the comments beside the fields and the reasons in palpd.settings_bounds;
- reference/scene.md: the scene file, from drivers.sim.scene's models;
- reference/bus.md: every bus message, command and reply, from the published JSON Schemas (`palpd schema`);
- history/changelog.md: CHANGELOG.md, which stays at the top of the repository where people look for it.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

from mkdocs.structure.files import File

sys.path.insert(0, str(Path(__file__).parent))  # the page builders beside this hook
from cli_pages import command_page
from model_pages import scene_page, settings_page
from schema_pages import bus_page


ROOT = Path(__file__).resolve().parents[2]


def changelog_page() -> str:
    """CHANGELOG.md as a page of the manual, its links into docs/ made relative to docs/history/."""
    return (ROOT / "CHANGELOG.md").read_text().replace("](docs/", "](../")


def on_files(files, config):
    os.environ["COLUMNS"] = "100"  # argparse wraps help to the terminal: the same width on every machine
    from palpd.cli import build_parser as palpd_parser
    from palpd.palpctl import build_parser as palpctl_parser

    pages = {
        "reference/palpd.md": command_page(palpd_parser(), "The `palpd` command"),
        "reference/palpctl.md": command_page(palpctl_parser(), "The `palpctl` command"),
        "reference/settings.md": settings_page(),
        "reference/scene.md": scene_page(),
        "reference/bus.md": bus_page(),
        "history/changelog.md": changelog_page(),
    }
    for path, content in pages.items():
        files.append(File.generated(config, path, content=content))
    return files
