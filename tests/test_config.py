import os
import tomllib

import pytest

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
