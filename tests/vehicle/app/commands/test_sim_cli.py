from __future__ import annotations

import json

import cv2
import pytest

from vehicle.app.cli import main


@pytest.fixture
def car(tmp_path, monkeypatch):
    """A car folder with a coarse texture, as the current directory."""
    (tmp_path / "myconfig.py").write_text("SIM_TEXTURE_RES = 0.02\n")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_sim_track_draws_png_and_camera_view(car, capsys):
    assert main(["sim", "track", "--seed", "7", "--png", "t.png", "--camera", "c.png", "--size", "300"]) == 0
    assert cv2.imread(str(car / "t.png")).shape == (300, 300, 3)
    assert cv2.imread(str(car / "c.png")).shape == (120, 160, 3)
    assert "track 7" in capsys.readouterr().out


def test_sim_eval_expert_prints_table_and_writes_reports(car, capsys):
    rc = main(["sim", "eval", "--pilot", "expert", "--tracks", "11,12", "--laps", "1",
               "--json", "r.json", "--png", "r.png"])
    assert rc == 0
    out = capsys.readouterr().out
    assert "autonomy" in out and "success rate 100 %" in out
    report = json.loads((car / "r.json").read_text())
    assert report["seeds"] == [11, 12] and report["overall"]["autonomy"] == 100.0
    assert (car / "r.png").stat().st_size > 1000


def test_sim_cli_errors_exit_2(car, capsys):
    assert main(["sim", "eval", "--pilot", "missing.pt", "--tracks", "1"]) == 2
    assert "no such model file" in capsys.readouterr().err
    assert main(["sim", "eval", "--pilot", "expert", "--tracks", "1", "--laps", "0"]) == 2
    with pytest.raises(SystemExit):
        main(["sim", "eval", "--pilot", "expert", "--tracks", "a,b"])
    (car / "myconfig.py").write_text("SIM_ROAD_WIDHT = 1.0\n")
    assert main(["sim", "track", "--seed", "1", "--png", "x.png"]) == 2
    assert "SIM_ROAD_WIDTH" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [
    ["sim", "track", "--seed", "7", "--png", "t.jpg2"],
    ["sim", "track", "--seed", "7", "--png", "t.png", "--camera", "c"],
    ["sim", "eval", "--pilot", "expert", "--tracks", "11", "--png", "r.svg"],
])
def test_sim_image_outputs_other_than_png_are_refused_before_any_work(car, capsys, argv):
    # acceptance: --png t.jpg2 ended in a cv2.error traceback (and eval --png only after the run)
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "expected a .png file name" in err.splitlines()[-1]
    assert not any(car.glob("*.png"))


def test_sim_record_command(car, capsys):
    assert main(["sim", "record", "--records", "25", "--tracks", "2", "--tub", "data/demo"]) == 0
    assert "recorded 25 records" in capsys.readouterr().out
    assert len((car / "data/demo/catalog_0.catalog").read_text().splitlines()) == 25


def test_eval_cli_names_the_conditions(tmp_path, capsys):
    code = main(["sim", "eval", "--pilot", "expert", "--tracks", "41,42", "--laps", "1", "--theme", "indoor,park",
                 "--randomize", "8", "--json", str(tmp_path / "r.json")])
    out = capsys.readouterr().out
    assert code == 0
    assert "conditions: theme indoor, park, randomised with seed 8" in out
    assert " indoor " in out and " park " in out
    for args, message in ((["--theme", "desert"], "unknown theme 'desert'"),
                          (["--randomize", "x"], "integer seed or 'off'")):
        with pytest.raises(SystemExit) as exc:  # argparse's usage error
            main(["sim", "eval", "--pilot", "expert", *args])
        assert exc.value.code == 2 and message in capsys.readouterr().err
    (tmp_path / "myconfig.py").write_text("SIM_LANES = 2\nSIM_THEME = ['road', 'park']\n")
    assert main(["sim", "eval", "--pilot", "expert", "--car", str(tmp_path)]) == 2
    assert "theme 'park' has no two-lane variant" in capsys.readouterr().err


def test_track_cli_draws_any_theme(tmp_path, capsys):
    assert main(["sim", "track", "--seed", "3", "--theme", "park", "--randomize", "2", "--png",
                 str(tmp_path / "t.png"), "--camera", str(tmp_path / "c.png"), "--size", "200"]) == 0
    cam = cv2.imread(str(tmp_path / "c.png"))
    assert cam.shape == (120, 160, 3)
    assert cv2.imread(str(tmp_path / "t.png")).shape == (200, 200, 3)


@pytest.mark.parametrize("model_type", ["behavior", "lanes"])
def test_sim_eval_of_a_behaviour_model_in_a_car_without_behaviours_says_what_to_set(car, capsys, make_model_file,
                                                                                     model_type):
    # issue 27: "input 'behavior/one_hot_state_array' is produced by no part ... declare it in
    # optional_inputs" (a developer's message); manage.py drive says to set TRAIN_BEHAVIORS = True
    model = make_model_file(model_type)
    assert main(["sim", "eval", "--pilot", str(model), "--tracks", "1", "--laps", "1"]) == 2
    err = capsys.readouterr().err
    assert "set TRAIN_BEHAVIORS = True in myconfig.py" in err, err
    assert "optional_inputs" not in err and "Traceback" not in err
    # ... and with it set, the model drives in its initial behaviour (BEHAVIOR_INITIAL), as in a drive
    (car / "myconfig.py").write_text("SIM_TEXTURE_RES = 0.02\nTRAIN_BEHAVIORS = True\n")
    assert main(["sim", "eval", "--pilot", str(model), "--tracks", "1", "--laps", "1", "--max-time", "2"]) == 0, \
        capsys.readouterr().err


def test_sim_eval_of_a_registered_model_fills_its_evaluation_column(car, capsys, make_model_file):
    """Hardening item 26: `vehicle models` showed an empty EVALUATION after `vehicle sim eval` of
    that model (only --store kept it). A registered model's evaluation is now kept unless
    --no-store."""
    from parts.pilots.modelfile import read_meta
    from training.model_db import ModelDB, register_model

    model = make_model_file("linear")
    register_model(model, read_meta(model))
    base = ["sim", "eval", "--pilot", str(model), "--tracks", "1", "--laps", "1", "--max-time", "2"]
    assert main([*base, "--no-store"]) == 0
    db = ModelDB.for_models_dir(car / "models")
    assert db.evaluations("linear") == []
    assert main(base) == 0
    assert "stored as evaluation" in capsys.readouterr().out
    [ev] = db.evaluations("linear")
    assert list(ev.tracks) == [1]
    assert main(["models"]) == 0
    row = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("linear"))
    assert f"{ev.overall['autonomy']:.1f}% on 1" in row
    unregistered = make_model_file("linear", name="loose")
    assert main(["sim", "eval", "--pilot", str(unregistered), "--tracks", "1", "--laps", "1", "--max-time", "2"]) == 0
    assert "not stored" in capsys.readouterr().out
