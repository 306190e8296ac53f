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


def test_settings_are_found_beside_their_families_with_no_list_to_keep():
    from vehicle.config import settings, settings_modules

    modules = settings_modules()
    assert modules[0] == "vehicle.settings"
    assert {"parts.cameras.settings", "parts.actuators.settings", "training.settings",
            "vehicle.app.console.settings"} <= set(modules)
    # the kernel declares only where files go and the loop; each family its own
    kernel = {s.section for s in settings().values() if s.module == "vehicle.settings"}
    assert kernel == {"Paths", "Vehicle loop"}
    assert settings()["CAMERA_TYPE"].module == "parts.cameras.settings"
    assert settings()["PWM_FREQ"].path.name == "settings.py"


def test_a_new_family_settings_module_is_collected(tmp_path, monkeypatch):
    """A package's settings.py is found at any depth; folders that are not packages are not."""
    from vehicle.config import parse_settings, settings_modules

    family = tmp_path / "probe_root" / "sensors" / "imu"
    family.mkdir(parents=True)
    for folder in (family.parent.parent, family.parent, family):
        (folder / "__init__.py").write_text("")
    (family / "settings.py").write_text("from typing import Annotated\nfrom vehicle.config_checks import Range\n"
                                        "# == IMU ==\n# Read rate of the IMU in Hz.\n"
                                        "IMU_HZ: Annotated[int, Range(1, 1000, unit='Hz')] = 100\n")
    (tmp_path / "probe_root" / "static").mkdir()
    (tmp_path / "probe_root" / "static" / "settings.py").write_text("X: int = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert settings_modules(("probe_root",))[1:] == ["probe_root.sensors.imu.settings"]
    imu = parse_settings("probe_root.sensors.imu.settings")["IMU_HZ"]
    assert (imu.section, imu.doc, imu.line, imu.annotation) == (
        "IMU", "Read rate of the IMU in Hz.", 5, "Annotated[int, Range(1, 1000, unit='Hz')]")


def test_every_setting_is_documented():
    from vehicle.config import settings

    undocumented = [s.name for s in settings().values() if not s.doc]
    assert undocumented == []


def test_donkeycar_name_gets_its_new_name():
    with pytest.raises(ConfigError, match="unknown setting WEB_INIT_MODE. Did you mean DEFAULT_MODE?"):
        Config.defaults(WEB_INIT_MODE="local")
    # acceptance: a DonkeyCar myconfig.py's DONKEY_GYM = True was pointed to DONKEY_GYM_ENV_NAME
    with pytest.raises(ConfigError, match='unknown setting DONKEY_GYM. Did you mean SIM_TYPE = "donkey"?'):
        Config.defaults(DONKEY_GYM=True)
    # DonkeyCar's drivetrain dict is a setting here too (docs/drivetrains.md)
    cfg = Config.defaults(PWM_STEERING_THROTTLE={"PWM_STEERING_PIN": "PCA9685.1:40.1"})
    assert cfg.PWM_STEERING_THROTTLE == {"PWM_STEERING_PIN": "PCA9685.1:40.1"}



def test_a_donkeycar_myconfig_gets_every_unknown_setting_in_one_message(tmp_path):
    # a myconfig.py copied from a DonkeyCar car failed on its first unknown setting, then on the
    # next one at the next run, and so on
    (tmp_path / "myconfig.py").write_text("import os\nDRIVE_LOOP_HZ = 20\nDONKEY_GYM = True\n"
                                          "WEB_INIT_MODE = 'user'\nHAVE_SOMBRERO = False\nMAX_LOOPS = 100\n")
    with pytest.raises(ConfigError) as info:
        load_config(car_path=tmp_path)
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith(f"{tmp_path.resolve() / 'myconfig.py'}: 3 unknown settings: DONKEY_GYM (line 3; did you "
                          'mean SIM_TYPE = "donkey"?), WEB_INIT_MODE (line 4; did you mean DEFAULT_MODE?), '
                          "HAVE_SOMBRERO (line 5")
    assert msg.endswith("Rename or delete them; docs/config.md lists every setting.")

# -- ranges and rules across settings (issue 21: items 2, 3, 10) ------------------------------------
#: (myconfig line, how the error starts, what it must say is valid)
OUT_OF_RANGE = [
    ("DRIVE_LOOP_HZ = -20", "DRIVE_LOOP_HZ = -20", "1 to 1000 Hz"),
    ("STEERING_LEFT_PWM = 5000", "STEERING_LEFT_PWM = 5000", "123 to 612 ticks"),
    ("THROTTLE_FORWARD_PWM = 4000", "THROTTLE_FORWARD_PWM = 4000", "500 to 2500 µs"),
    ('WEB_DEADMAN_S = float("nan")', "WEB_DEADMAN_S = nan", "0.1 to 2 s"),
    ("WEB_DEADMAN_S = 1e9", "WEB_DEADMAN_S = 1000000000.0", "0.1 to 2 s"),
    ("ACTUATOR_WATCHDOG_S = 1e9", "ACTUATOR_WATCHDOG_S = 1000000000.0", "None switches it off"),
    ("ACTUATOR_WATCHDOG_S = 0", "ACTUATOR_WATCHDOG_S = 0", "None switches it off"),
    ('WEB_TOKEN = "short"', "WEB_TOKEN (5 characters)", "at least 8 characters"),
    ('WEB_TOKEN = "12345678"', "WEB_TOKEN (8 characters) is too weak (about 27 bits", "about 64 bits"),
    ("WEB_MAX_THROTTLE = 2.0", "WEB_MAX_THROTTLE = 2.0", "0 to 1"),
    ("AI_THROTTLE_MULT = -1.0", "AI_THROTTLE_MULT = -1.0", "0 to 2"),
    ("THROTTLE_STOPPED_PWM = 600", "THROTTLE_STOPPED_PWM = 600", "between THROTTLE_REVERSE_PWM"),
    ("STEERING_RIGHT_PWM = 460", "STEERING_LEFT_PWM and STEERING_RIGHT_PWM are both 460", "differ"),
    ("JOYSTICK_SILENCE_TIMEOUT_S = 3600.0", "JOYSTICK_SILENCE_TIMEOUT_S = 3600.0", "None switches it off"),
    ("THROTTLE_CHANNEL = 1", "STEERING_CHANNEL and THROTTLE_CHANNEL are both 1", "two different channels"),
    ("TUB_TYPES = ['image_array', 'float']", "TUB_TYPES = ['image_array', 'float']", "one type per TUB_INPUTS"),
    ("TUB_TYPES = ['image_array', 'float', 'double', 'str']", "TUB_TYPES = ['image_array', 'float', 'double', "
     "'str'] holds 'double', which is unknown", 'one of "float", "int", "str", "boolean", "nparray"'),
    ("BEHAVIOR_INITIAL = 5", "BEHAVIOR_INITIAL = 5", "0 to 1"),
]


@pytest.mark.parametrize("line, start, valid", OUT_OF_RANGE, ids=[c[0] for c in OUT_OF_RANGE])
def test_out_of_range_values_are_one_line_errors_with_file_line_and_valid_range(tmp_path, line, start, valid):
    write(tmp_path, f"# my car\n{line}\n")
    with pytest.raises(ConfigError) as info:
        load_config(car_path=tmp_path)
    msg = str(info.value)
    assert msg.startswith(f"{tmp_path.resolve() / 'myconfig.py'}, line 2: {start}"), msg
    assert valid in msg and "\n" not in msg
    for internal in ("deadman_s", "max_throttle", "ai_throttle_mult", "watchdog_s", "forward="):
        assert internal not in msg


def test_a_setting_that_breaks_another_is_located_at_its_own_line(tmp_path):
    # at 400 Hz a tick is 0.61 µs: the default steering pulse of 460 ticks would be 281 µs
    write(tmp_path, "DRIVE_LOOP_HZ = 20\nPWM_FREQ = 400\n")
    with pytest.raises(ConfigError) as info:
        load_config(car_path=tmp_path)
    msg = str(info.value)
    assert msg.startswith(f"{tmp_path.resolve() / 'myconfig.py'}, line 2: ")
    assert "STEERING_LEFT_PWM = 460" in msg and "PWM_FREQ = 400" in msg and "µs" in msg


def test_a_setting_set_twice_is_located_at_the_assignment_in_effect(tmp_path):
    write(tmp_path, "DRIVE_LOOP_HZ = 20\nWEB_JPEG_QUALITY = 80\nWEB_JPEG_QUALITY = 0\n")
    with pytest.raises(ConfigError, match=r", line 3: WEB_JPEG_QUALITY = 0 "):
        load_config(car_path=tmp_path)


def test_the_watchdog_must_outlast_two_loops(tmp_path):
    write(tmp_path, "DRIVE_LOOP_HZ = 5\nACTUATOR_WATCHDOG_S = 0.2\n")
    with pytest.raises(ConfigError, match=r"line 2: ACTUATOR_WATCHDOG_S = 0.2 .*two loops at DRIVE_LOOP_HZ = 5"):
        load_config(car_path=tmp_path)


def test_valid_edges_load_and_code_overrides_are_checked_too(tmp_path):
    write(tmp_path, "THROTTLE_FORWARD_PWM = 612\nTHROTTLE_REVERSE_PWM = 123\nWEB_DEADMAN_S = 2.0\n"
                    "ACTUATOR_WATCHDOG_S = None\nWEB_TOKEN = 'Ab3$efGh9!'\n")
    cfg = load_config(car_path=tmp_path)
    assert (cfg.THROTTLE_FORWARD_PWM, cfg.ACTUATOR_WATCHDOG_S) == (612, None)
    with pytest.raises(ConfigError, match=r"^DRIVE_LOOP_HZ = 0 is out of range; valid: 1 to 1000 Hz"):
        Config.defaults(DRIVE_LOOP_HZ=0)
    with pytest.raises(ConfigError, match="WEB_MAX_THROTTLE = 1.5"):
        cfg.replace(WEB_MAX_THROTTLE=1.5)
    with pytest.raises(ConfigError, match="WEB_JPEG_QUALITY = 0"):
        cfg.WEB_JPEG_QUALITY = 0


def test_every_number_setting_declares_its_range():
    from vehicle.config import settings

    unchecked = [s.name for s in settings().values()
                 if any(t in s.annotation for t in ("int", "float")) and "Annotated" not in s.annotation
                 and "Literal" not in s.annotation]
    assert unchecked == []


def test_manage_py_prints_one_line_and_exits_2(tmp_path, capsys):
    from vehicle.app import manage as car

    for line in ("DRIVE_LOOP_HZ = -20", "STEERING_LEFT_PWM = 5000", 'WEB_DEADMAN_S = float("nan")',
                 'WEB_TOKEN = "short"'):
        write(tmp_path, line + "\n")
        parser = car.command_parser("test car")
        car.add_command(parser, "drive", lambda cfg, args: 0, "drive")
        assert car.main(parser, tmp_path, ["drive"]) == 2
        err = capsys.readouterr().err
        assert err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err, err
        assert "line 1" in err
