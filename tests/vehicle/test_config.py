from __future__ import annotations

import pytest

from vehicle.config import Config, ConfigError, load_config
from vehicle.config_docs import DOC_PATH, render


def write(tmp_path, text, name="myconfig.py"):
    (tmp_path / name).write_text(text)
    return tmp_path


def test_overrides_and_derived_values_recomputed(tmp_path):
    cfg = load_config(car_path=write(tmp_path, "DRIVE_LOOP_HZ = 50\nIMAGE_W = 320\n"))
    assert cfg.DRIVE_LOOP_HZ == 50
    assert cfg.CAMERA_FRAMERATE == 50  # derived from DRIVE_LOOP_HZ after the override
    assert cfg.IMAGE_W == 320 and cfg.IMAGE_H == 120
    assert cfg.CAR_PATH == str(tmp_path.resolve())
    assert cfg.path("DATA_PATH") == tmp_path.resolve() / "data"
    assert cfg.overridden >= {"DRIVE_LOOP_HZ", "IMAGE_W"}


def test_explicit_derived_value_wins(tmp_path):
    cfg = load_config(car_path=write(tmp_path, "DRIVE_LOOP_HZ = 50\nCAMERA_FRAMERATE = 30\n"))
    assert (cfg.DRIVE_LOOP_HZ, cfg.CAMERA_FRAMERATE) == (50, 30)


def test_unknown_name_names_file_line_and_closest(tmp_path):
    write(tmp_path, "import math\n\nDRIVE_LOOP_HZ = 20\nDRIVE_LOP_HZ = 30\n")
    with pytest.raises(ConfigError) as info:
        load_config(car_path=tmp_path)
    msg = str(info.value)
    assert f"{tmp_path.resolve() / 'myconfig.py'}, line 4: unknown setting DRIVE_LOP_HZ." in msg
    assert "Did you mean DRIVE_LOOP_HZ?" in msg


def test_wrong_type_names_expected_type(tmp_path):
    write(tmp_path, "DRIVE_LOOP_HZ = '20'\n")
    with pytest.raises(ConfigError, match=r"line 1: DRIVE_LOOP_HZ = '20' has type str, expected int"):
        load_config(car_path=tmp_path)


def test_enum_and_optional_and_callable_types():
    assert Config.defaults(MAX_LOOPS=None).MAX_LOOPS is None
    assert Config.defaults(AI_THROTTLE_MULT=1).AI_THROTTLE_MULT == 1  # an int is a valid float
    expected = r"DEFAULT_MODE = 'auto' .* expected \"user\" \| \"local_angle\" \| \"local\""
    with pytest.raises(ConfigError, match=expected):
        Config.defaults(DEFAULT_MODE="auto")
    with pytest.raises(ConfigError, match="expected int"):
        Config.defaults(IMAGE_W=True)  # a bool is not an int here
    with pytest.raises(ConfigError, match=r"TRAIN_FILTER = 3 has type int, expected Callable"):
        Config.defaults(TRAIN_FILTER=3)
    assert Config.defaults(TRAIN_FILTER=lambda r: True).TRAIN_FILTER({}) is True


def test_syntax_error_and_runtime_error_are_reported(tmp_path):
    write(tmp_path, "DRIVE_LOOP_HZ = = 3\n")
    with pytest.raises(ConfigError, match=r"line 1: invalid Python"):
        load_config(car_path=tmp_path)
    write(tmp_path, "DRIVE_LOOP_HZ = 1 / 0\n")
    with pytest.raises(ConfigError, match="running the config file failed: ZeroDivisionError"):
        load_config(car_path=tmp_path)


def test_myconfig_option_selects_another_file(tmp_path):
    write(tmp_path, "DRIVE_LOOP_HZ = 10\n")
    write(tmp_path, "DRIVE_LOOP_HZ = 40\n", name="race.py")
    assert load_config(car_path=tmp_path).DRIVE_LOOP_HZ == 10
    assert load_config("race.py", car_path=tmp_path).DRIVE_LOOP_HZ == 40
    with pytest.raises(ConfigError, match="no such config file"):
        load_config("missing.py", car_path=tmp_path)


def test_missing_default_myconfig_means_defaults(tmp_path):
    assert load_config(car_path=tmp_path).DRIVE_LOOP_HZ == Config.defaults().DRIVE_LOOP_HZ


def test_replace_and_attribute_errors():
    cfg = Config.defaults().replace(DRIVE_LOOP_HZ=40)
    assert cfg.CAMERA_FRAMERATE == 40
    with pytest.raises(AttributeError, match="did you mean DRIVE_LOOP_HZ"):
        _ = cfg.DRIVE_LOOP_H
    with pytest.raises(ConfigError, match="unknown setting"):
        cfg.NOT_A_SETTING = 1


def test_config_reference_is_in_sync():
    assert DOC_PATH.read_text() == render(), "run: python -m vehicle.config_docs"


def test_every_setting_is_documented():
    from vehicle.config import settings

    undocumented = [s.name for s in settings().values() if not s.doc]
    assert undocumented == []


def test_donkeycar_name_gets_its_new_name():
    with pytest.raises(ConfigError, match="unknown setting WEB_INIT_MODE. Did you mean DEFAULT_MODE?"):
        Config.defaults(WEB_INIT_MODE="local")
