"""The manual builds with `mkdocs build --strict` (offline: no plugin fetches anything), and its generated
reference names every palpd and palpctl subcommand and every setting of config/palpd.toml; the README stays a
front door."""
import re
import subprocess
import sys
import tomllib
from html import unescape

import pytest

from conftest import ROOT
from palpd.cli import build_parser as palpd_parser
from palpd.palpctl import build_parser as palpctl_parser

sys.path.insert(0, str(ROOT / "docs" / "hooks"))
from cli_pages import subcommands  # noqa: E402  the hook's own walk of the parsers


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    out = tmp_path_factory.mktemp("site")
    built = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
                           cwd=ROOT, capture_output=True, text=True, timeout=300,
                           env={"NO_MKDOCS_2_WARNING": "1", "PATH": "/usr/bin:/bin", "HOME": str(out)})
    assert built.returncode == 0, built.stderr[-3000:]
    return out


def page_text(site, page: str) -> str:
    html = (site / page / "index.html").read_text()
    return unescape(re.sub(r"<[^>]+>", " ", html))


def test_the_command_reference_names_every_palpd_and_palpctl_subcommand(site):
    for parser, page in ((palpd_parser(), "reference/palpd"), (palpctl_parser(), "reference/palpctl")):
        text = " ".join(page_text(site, page).split())
        names = [name for name, _, _ in subcommands(parser)]
        assert len(names) >= 9
        for name in names:
            assert f"{parser.prog} {name}" in text, f"{page} does not name {parser.prog} {name}"
        assert "usage:" in text


def test_the_settings_reference_has_every_key_of_the_shipped_config_in_its_section(site):
    text = page_text(site, "reference/settings")
    sections = re.split(r"\[(\w+)\]\s*¶", text)  # the headings "[robot]¶", "[sensor]¶" ... and what follows each
    by_section = dict(zip(sections[1::2], sections[2::2]))
    shipped = tomllib.loads((ROOT / "config" / "palpd.toml").read_text())
    for section, keys in shipped.items():
        assert section in by_section, f"no [{section}] on the settings page"
        for key in keys:
            assert re.search(rf"(^|\s){key}\s", by_section[section]), f"{section}.{key} missing"


def test_the_generated_pages_carry_defaults_bounds_and_every_schema(site):
    settings = " ".join(page_text(site, "reference/settings").split())
    assert "current_limit_a float 5.5 > 0, ≤ 5.5 A" in settings  # type, default, bounds, unit from the model
    bus = page_text(site, "reference/bus")
    for name in ("status", "estimate", "reply.probe.at", "scan.start.args", "error"):
        assert name in bus
    assert "radius_mm" in page_text(site, "reference/scene")
    assert "simulate_scan" in page_text(site, "reference/api")


def test_the_readme_is_a_front_door_of_at_most_200_lines_that_keeps_the_two_make_commands():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 200
    assert "make run" in readme and "make test" in readme
    for link in re.findall(r"\]\(((?:docs/|CHANGELOG)[^)#]*)", readme):
        assert (ROOT / link).exists(), f"README links to {link}, which is not there"


def figures_script():
    sys.path.insert(0, str(ROOT / "scripts"))
    import figures

    return figures


def test_the_readmes_figures_are_the_ones_make_figures_wrote_and_say_which_commit_they_measured():
    figures = figures_script()
    readme = (ROOT / "README.md").read_text()
    names = re.findall(r"<!-- figures:([\w-]+) -->", readme)
    assert {"scans", "paper-map"} <= set(names)
    for name in names:
        written = (ROOT / "docs" / "figures" / f"{name}.md").read_text()
        assert figures.marked(name).search(readme).group(2) == written  # copied, not typed
        assert re.search(r"at commit [0-9a-f]{7,}", written), written


def test_make_figures_stamps_a_dirty_tree_uncommitted_and_rewrites_only_between_its_markers(tmp_path):
    figures = figures_script()
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t"]
    subprocess.run([*git, "init", "-q", str(tmp_path)], check=True)
    readme = tmp_path / "README.md"
    readme.write_text("before\n<!-- figures:scans -->\nold\n<!-- /figures:scans -->\nafter\n")
    subprocess.run([*git, "add", "-A"], cwd=tmp_path, check=True)
    subprocess.run([*git, "commit", "-qm", "x"], cwd=tmp_path, check=True)
    figures.copy_into_readme("scans", "new table\n", readme)
    assert readme.read_text() == "before\n<!-- figures:scans -->\nnew table\n<!-- /figures:scans -->\nafter\n"
    assert "uncommitted" not in figures.commit_stamp(tmp_path)  # the README is what it writes itself
    (tmp_path / "code.py").write_text("changed = True\n")
    assert figures.commit_stamp(tmp_path).endswith("(uncommitted changes)")


def test_the_calibration_figure_says_the_trade_from_its_own_rows():
    """The README's "how many fewer palpations" is the calibration table's own sums, tightest row against loosest."""
    table = ("| tolerance mm | confidence | palpations (sum) | median |\n|---|---|---|---|\n"
             "| 0.25 | 0.9 | 800 | 37 |\n| 0.5 | 0.9 | 700 | 30 |\n| 2 | 0.9 | 600 | 23 |")
    assert figures_script().trade(table) == "2 mm took 25% fewer palpations than 0.25 mm"
