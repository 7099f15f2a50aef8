import json
import math
import os
import tomllib

import pytest
from hypothesis import given, strategies as st

from conftest import ROOT, assert_one_line_error
from palpd.config import Settings, load_settings
from palpd.errors import EXIT_CONFIG, ConfigError


def write(tmp_path, text, name="palpd.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_shipped_config_equals_the_built_in_defaults():
    shipped = tomllib.loads((ROOT / "config" / "palpd.toml").read_text())
    assert Settings.model_validate(shipped) == Settings()
    assert load_settings(ROOT / "config" / "palpd.toml", environ={}) == Settings()


def test_file_values_override_defaults(tmp_path):
    settings = load_settings(write(tmp_path, "[palpation]\ndepth_mm = 6.5\n"), environ={})
    assert settings.palpation.depth_mm == 6.5
    assert settings.palpation.speed_mm_s == Settings().palpation.speed_mm_s


@pytest.mark.parametrize("text, path", [
    ("colour = 1\n", "colour"),
    ("[palpation]\ndepht_mm = 3\n", "palpation.depht_mm"),
    ("[safety]\nforce_cap_n = 5\nextra = true\n", "safety.extra"),
])
def test_unknown_keys_are_refused_at_every_level(tmp_path, text, path):
    config = write(tmp_path, text)
    with pytest.raises(ConfigError) as error:
        load_settings(config, environ={})
    assert str(error.value) == f"{config}: {path}: unknown key"


def test_wrong_type_names_file_path_and_expectation(tmp_path):
    config = write(tmp_path, '[palpation]\ndepth_mm = "deep"\n')
    with pytest.raises(ConfigError) as error:
        load_settings(config, environ={})
    message = str(error.value)
    assert message.startswith(f"{config}: palpation.depth_mm: ")
    assert "number" in message and "'deep'" in message


def test_cross_field_rule_is_checked(tmp_path):
    config = write(tmp_path, "[palpation]\nmax_force_n = 7.0\n")
    with pytest.raises(ConfigError, match="must be below safety.force_cap_n"):
        load_settings(config, environ={})


def test_missing_and_malformed_files(tmp_path):
    with pytest.raises(ConfigError, match="config file not found"):
        load_settings(tmp_path / "nope.toml", environ={})
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_settings(write(tmp_path, "[palpation\n"), environ={})


def test_environment_overrides_nested_keys(tmp_path):
    env = {"PALPD_PALPATION__DEPTH_MM": "5.5", "PALPD_SCAN__STRATEGY": "random", "HOME": "/x"}
    settings = load_settings(write(tmp_path, "[palpation]\ndepth_mm = 3\n"), environ=env)
    assert settings.palpation.depth_mm == 5.5
    assert settings.scan.strategy == "random"


def test_environment_errors_name_the_variable():
    with pytest.raises(ConfigError) as error:
        load_settings(environ={"PALPD_PALPATION__DEPTH_MM": "lots"})
    assert str(error.value).startswith("environment PALPD_PALPATION__DEPTH_MM: palpation.depth_mm: ")
    with pytest.raises(ConfigError, match="environment PALPD_PALPATION__NOPE: palpation.nope: unknown key"):
        load_settings(environ={"PALPD_PALPATION__NOPE": "1"})


def test_command_line_overrides_are_validated():
    with pytest.raises(ConfigError, match="command line: palpation.depth_mm"):
        Settings().updated(palpation={"depth_mm": -1.0})
    assert Settings().updated(palpation={"depth_mm": 2.0, "speed_mm_s": None}).palpation.depth_mm == 2.0


@pytest.mark.parametrize("text, fragments", [
    ("[palpation]\nbogus = 1\n", ["palpation.bogus", "unknown key"]),
    ("[palpation]\ndepth_mm = [1]\n", ["palpation.depth_mm", "valid number"]),
])
def test_cli_config_errors_are_one_line_with_config_exit_status(tmp_path, run_cli, text, fragments):
    config = write(tmp_path, text)
    result = run_cli("scan", "--scene", ROOT / "config/scenes/paper.toml", "--config", config)
    assert_one_line_error(result, str(config), *fragments)
    assert result.returncode == EXIT_CONFIG


def test_cli_missing_config_file(tmp_path, run_cli):
    result = run_cli("scan", "--scene", ROOT / "config/scenes/paper.toml", "--config", tmp_path / "missing.toml")
    assert_one_line_error(result, "missing.toml", "not found")


def test_cli_environment_error(run_cli):
    env = dict(os.environ, PALPD_SAFETY__FORCE_CAP_N="-3")
    result = run_cli("scan", "--scene", ROOT / "config/scenes/paper.toml", env=env)
    assert_one_line_error(result, "PALPD_SAFETY__FORCE_CAP_N", "safety.force_cap_n")


def _numbers(section, names=lambda name: True) -> set[str]:
    return {name for name, value in section if names(name) and isinstance(value, (int, float))
            and not isinstance(value, bool)}


def test_every_safety_and_timing_limit_has_a_bound_with_a_reason():
    from palpd.settings_bounds import BOUNDS

    defaults = Settings()
    wanted = {f"safety.{name}" for name in _numbers(defaults.safety)}
    for section in ("robot", "sensor", "servo", "daemon", "palpation"):  # durations, rates, speeds
        wanted |= {f"{section}.{name}" for name in _numbers(getattr(defaults, section), lambda n: n.endswith(("_s", "_hz")))}
    assert wanted - set(BOUNDS) == set(), "limits without a bound: add rows to palpd.settings_bounds.BOUNDS"
    for dotted, bound in BOUNDS.items():
        section, key = dotted.split(".")
        assert bound.problem(getattr(getattr(defaults, section), key)) is None, dotted  # defaults are sane
        assert len(bound.why) > 10


@given(st.sampled_from(sorted(__import__("palpd.settings_bounds", fromlist=["BOUNDS"]).BOUNDS.items())),
       st.floats(1.0001, 1e12) | st.sampled_from([math.inf, math.nan]))
def test_a_limit_beyond_its_bound_is_refused_with_the_reason(item, factor):
    dotted, bound = item
    section, key = dotted.split(".")
    value = bound.high * factor if math.isfinite(factor) else factor
    with pytest.raises(ConfigError) as error:
        load_settings(environ={f"PALPD_{section.upper()}__{key.upper()}": json.dumps(value)})
    message = str(error.value)
    assert message.startswith(f"environment PALPD_{section.upper()}__{key.upper()}: {dotted} = ")
    assert (f"at most {bound.high:g} {bound.unit}; {bound.why}" in message if math.isfinite(value)
            else "finite" in message)


@pytest.mark.parametrize("text, fragments", [
    ("[safety]\nworkspace_z_mm = [80.0, -20.0]\n", ["safety.workspace_z_mm [80.0, -20.0] is inverted"]),
    ("[safety]\nworkspace_z_mm = [-2.0, 80.0]\n", ["safety.workspace_z_mm starts at -2", "palpation.depth_mm = 4"]),
    ("[safety]\nworkspace_z_mm = [-20.0, 3.0]\n", ["ends at 3 mm", "palpation.clearance_mm"]),
    ("[control]\nvelocity_filter_hz = 600.0\n", ["control.velocity_filter_hz = 600", "servo.rate_hz"]),
    ("[safety]\nmax_sample_age_s = 0.0005\n", ["safety.max_sample_age_s = 0.0005", "one servo period"]),
])
def test_inconsistent_settings_are_refused_naming_the_fields(tmp_path, text, fragments):
    config = write(tmp_path, text)
    with pytest.raises(ConfigError) as error:
        load_settings(config, environ={})
    assert str(error.value).startswith(f"{config}: ")
    for fragment in fragments:
        assert fragment in str(error.value)


@pytest.mark.parametrize("text, fragments", [
    ("[safety]\nmax_tick_gap_s = 1000\n", ["safety.max_tick_gap_s = 1000: at most 0.1 s; a longer gap is no longer servo control"]),
    ("[safety]\nworkspace_z_mm = [80.0, -20.0]\n", ["safety.workspace_z_mm", "inverted"]),
    ("[tissue]\norigin_mm = [0.0, -60.0, -400.0]\n[robot]\nurl = \"socket://127.0.0.1:1\"\n"
     "[sensor]\nbackend = \"netft://127.0.0.1:1\"\n", ["tissue.origin_mm", "out of the arm's reach"]),
    # ZeroMQ bound port 99999 without a word, and "garbage" was called a non-loopback endpoint needing keys
    ("[bus]\nevents = \"tcp://127.0.0.1:99999\"\n", ["bus.events", "port from 1 to 65535", "99999"]),
    ("[bus]\ncommands = \"garbage\"\n", ["bus.commands", "not a ZeroMQ endpoint", "garbage"]),
    ("[tissue]\nsize_mm = [1000.0, 60.0]\n", ["tissue.size_mm.0", "less than or equal to 758"]),
])
def test_serve_refuses_unbounded_or_inconsistent_settings_with_one_line_and_78(tmp_path, run_cli, text, fragments):
    result = run_cli("serve", "--config", write(tmp_path, text), env=dict(os.environ, PALPD_DAEMON__HTTP=""))
    assert_one_line_error(result, *fragments)
    assert result.returncode == EXIT_CONFIG


def test_a_bad_scene_exits_78_like_a_bad_config(tmp_path, run_cli):
    scene = write(tmp_path, "name = 'x'\n[tissue]\nsize_mm = [-1.0, 5.0]\n", "scene.toml")
    for command in (["scan", "--scene", scene], ["serve", "--scene", scene], ["simulate", "--scene", scene]):
        result = run_cli(*command, env=dict(os.environ, PALPD_DAEMON__HTTP=""))
        assert_one_line_error(result, "scene.toml", "tissue.size_mm")
        assert result.returncode == EXIT_CONFIG, command
