from __future__ import annotations

import ast
import re
import subprocess
import sys
from importlib import resources
from pathlib import Path

import pytest

from vehicle.app.commands.createcar import CAR_DIRS, create_car, templates
from vehicle.config import ConfigError, check_value
from vehicle.errors import UserError

REPO = Path(__file__).resolve().parents[4]


def test_templates_include_basic_and_simulator():
    assert {"basic", "simulator", "path_follow"} <= set(templates())


@pytest.mark.parametrize("template", ["basic", "simulator", "path_follow"])
def test_createcar_writes_car_folder(tmp_path, template):
    car = tmp_path / "car"
    result = create_car(car, template)
    assert sorted(result.written) == ["manage.py", "myconfig.py"]
    assert all((car / d).is_dir() for d in CAR_DIRS)
    assert (car / "manage.py").stat().st_mode & 0o100
    ast.parse((car / "manage.py").read_text())
    # myconfig holds only comments and a docstring: no active override
    tree = ast.parse((car / "myconfig.py").read_text())
    assert [type(n).__name__ for n in tree.body] == ["Expr"]


def test_existing_files_kept_and_myconfig_never_overwritten(tmp_path):
    create_car(tmp_path, "simulator")
    (tmp_path / "manage.py").write_text("# mine\n")
    (tmp_path / "myconfig.py").write_text("DRIVE_LOOP_HZ = 33\n")
    result = create_car(tmp_path, "basic")
    assert result.kept == ["manage.py", "myconfig.py"] and result.written == []
    assert (tmp_path / "manage.py").read_text() == "# mine\n"
    result = create_car(tmp_path, "basic", overwrite=True)
    assert result.written == ["manage.py"] and result.kept == ["myconfig.py"]
    assert "PWM drivetrain" in (tmp_path / "manage.py").read_text()
    assert (tmp_path / "myconfig.py").read_text() == "DRIVE_LOOP_HZ = 33\n"


def test_bad_template_and_path(tmp_path):
    with pytest.raises(UserError, match="unknown template 'race'; choose one of: .*basic"):
        create_car(tmp_path, "race")
    (tmp_path / "file").write_text("x")
    with pytest.raises(UserError, match="exists and is not a folder"):
        create_car(tmp_path / "file", "basic")


@pytest.mark.parametrize("template", ["basic", "simulator", "path_follow"])
def test_commented_settings_in_templates_are_valid(template):
    """Every `# NAME = value` suggestion in a template's myconfig.py would load if uncommented."""
    text = (resources.files("templates") / template / "myconfig.py").read_text()
    suggestions = re.findall(r"^# ([A-Z][A-Z0-9_]+) = (.+?)(?:\s+#.*)?$", text, flags=re.M)
    assert len(suggestions) >= 5
    for name, value in suggestions:
        try:
            check_value(name, ast.literal_eval(value))
        except ConfigError as exc:
            pytest.fail(f"templates/{template}/myconfig.py suggests {name} = {value}: {exc}")


def test_mycar_is_a_fresh_simulator_car(tmp_path):
    create_car(tmp_path, "simulator")
    for name in ("manage.py", "myconfig.py"):
        assert (REPO / "mycar" / name).read_text() == (tmp_path / name).read_text(), (
            f"mycar/{name} differs from a fresh createcar: run "
            "`vehicle createcar --path mycar --template simulator --overwrite` and review")


def test_cli_createcar_and_help(tmp_path):
    out = subprocess.run([sys.executable, "-m", "vehicle", "createcar", "--path", str(tmp_path / "c"),
                          "--template", "basic"], capture_output=True, text=True, check=True)
    assert "car ready" in out.stdout and (tmp_path / "c" / "manage.py").exists()
    bad = subprocess.run([sys.executable, "-m", "vehicle", "createcar", "--template", "nope"],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "invalid choice: 'nope'" in bad.stderr
    helped = subprocess.run([sys.executable, "-m", "vehicle", "--help"], capture_output=True, text=True)
    assert helped.returncode == 0 and "createcar" in helped.stdout
