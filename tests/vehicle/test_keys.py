"""Standard memory keys are declared beside their families (``keys.py``) and collected by the kernel."""

from __future__ import annotations

import pytest

from vehicle.discovery import family_modules
from vehicle.keys import KEYS, STANDARD_KEYS, KeyDeclarationError, KeyInfo, collect_keys, describe, key_names
from vehicle.vehicle import LOOP_KEYS


def _package(root, *names):
    """Folders ``root/names[0]/names[1]/...``, each a package; returns the innermost."""
    folder = root
    for name in names:
        folder = folder / name
        folder.mkdir(exist_ok=True)
        (folder / "__init__.py").write_text("")
    return folder


def _keys_module(folder, body: str) -> None:
    (folder / "keys.py").write_text(f"from vehicle.keys import KeyInfo\nKEYS = {{{body}}}\n")


def test_every_family_declares_its_own_keys_and_the_kernel_only_the_loops():
    table = collect_keys()
    assert set(KEYS) == set(LOOP_KEYS) == {"loop/rate_hz", "loop/overruns", "loop/count"}
    assert {k for k, m in table.module.items() if m == "vehicle.keys"} == set(KEYS)
    assert table.module["imu/acl_x"] == "parts.sensors.keys"
    assert table.module["cam/image_array"] == "parts.cameras.keys"
    assert table.module["web/angle"] == "parts.web.keys"
    assert table.module["sim/cte"] == "parts.sim.keys"
    assert describe("imu/gyr_z") == KeyInfo("float, rad/s", "IMU rotation rate about z (counter-clockwise seen "
                                                            "from above)")
    assert describe("imu/not_a_key") is None
    # the same walk finds settings.py and keys.py: one mechanism
    assert set(family_modules("keys.py")) == set(table.module.values()) - {"vehicle.keys"}


def test_standard_keys_without_a_namespace_are_donkeycars():
    assert sorted(k for k in STANDARD_KEYS if "/" not in k) == ["angle", "estop", "recording", "run_pilot",
                                                                 "throttle"]


def test_old_key_names_are_declared_beside_their_family():
    assert key_names("cam/left_image_array") == ("cam/left_image_array", "cam/image_array_left")
    assert key_names("cam/image_array_right") == ("cam/image_array_right", "cam/right_image_array")
    assert key_names("user/angle") == ("user/angle",)


def test_a_new_family_keys_module_is_found_with_no_list_to_edit(tmp_path, monkeypatch):
    """``parts/path/keys.py`` (any depth) is collected; a folder that is not a package is not."""
    _keys_module(_package(tmp_path, "probe_keys", "path"),
                 '"path/cte": KeyInfo("float, m", "distance to the recorded path")')
    _keys_module(_package(tmp_path, "probe_keys", "sensors", "imu"),
                 '"imu/temp": KeyInfo("float, degC", "die temperature")')
    (tmp_path / "probe_keys" / "static").mkdir()
    (tmp_path / "probe_keys" / "static" / "keys.py").write_text("KEYS = {'static/x': None}\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    table = collect_keys(("probe_keys",))
    assert table.module == {**dict.fromkeys(KEYS, "vehicle.keys"), "path/cte": "probe_keys.path.keys",
                            "imu/temp": "probe_keys.sensors.imu.keys"}
    assert table.keys["path/cte"] == KeyInfo("float, m", "distance to the recorded path")


def test_a_key_declared_by_two_families_is_a_clear_error(tmp_path, monkeypatch):
    _keys_module(_package(tmp_path, "probe_twice", "gps"), '"imu/acl_x": KeyInfo("float", "x")')
    _keys_module(_package(tmp_path, "probe_twice", "imu"), '"imu/acl_x": KeyInfo("float", "again")')
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(KeyDeclarationError, match=r"probe_twice/imu/keys\.py: memory key 'imu/acl_x' is already "
                                                  r"declared in probe_twice\.gps\.keys; declare each key once"):
        collect_keys(("probe_twice",))


def test_a_kernel_key_declared_again_by_a_family_is_an_error(tmp_path, monkeypatch):
    _keys_module(_package(tmp_path, "probe_loop", "x"), '"loop/count": KeyInfo("int", "mine")')
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(KeyDeclarationError, match="'loop/count' is already declared in vehicle.keys"):
        collect_keys(("probe_loop",))


@pytest.mark.parametrize(("body", "why"), [
    ("X = 1", "define KEYS: dict"),
    ("KEYS = {'a/b': ('float', 'x')}", r"KEYS\['a/b'\] must map a key string to KeyInfo"),
    ("from vehicle.keys import KeyInfo\nKEYS = {}\nALIASES = {'a/old': 'a/new'}", "must map an old name to a "
                                                                                 "declared standard key"),
])
def test_a_malformed_keys_module_is_named(tmp_path, monkeypatch, body, why):
    root = f"probe_bad_{abs(hash(body))}"
    (_package(tmp_path, root, "fam") / "keys.py").write_text(body + "\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(KeyDeclarationError, match=why):
        collect_keys((root,))


def test_key_reference_is_in_sync():
    from vehicle.config_docs import KEYS_DOC_PATH, render_keys

    assert KEYS_DOC_PATH.read_text() == render_keys(), "run: python -m vehicle.config_docs"
