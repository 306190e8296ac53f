"""DAgger in the built-in simulator: roll-outs labelled by the expert, rounds, the table, Ctrl-C."""

from __future__ import annotations

import json

import numpy as np
import pytest

from parts.tub import Tub
from vehicle.app.dagger import DaggerPlan, Labeller, format_rounds, rollout, run_dagger
from vehicle.config import Config


@pytest.fixture
def car_cfg(tmp_path):
    return Config.defaults(CAR_PATH=str(tmp_path), SIM_TEXTURE_RES=0.02, SIM_REALTIME=False, BATCH_SIZE=16,
                           MAX_EPOCHS=1, TRAIN_NUM_WORKERS=0, SHOW_PLOT=False, ROI_CROP_TOP=40)


class Swerve:
    """A pilot that steers hard left at a fixed throttle: it errs all the time."""

    def __init__(self, interrupt_at: int | None = None):
        self.frames, self.interrupt_at = 0, interrupt_at

    def run(self, image):
        self.frames += 1
        if self.interrupt_at is not None and self.frames >= self.interrupt_at:
            raise KeyboardInterrupt
        return -1.0, 0.4


class Actuator:
    """A stand-in drivetrain after the drive mode: what it was told last, and whether it went neutral."""

    INPUTS = ("angle", "throttle")

    def __init__(self):
        self.throttle, self.neutral_calls = None, 0

    def run(self, angle, throttle):
        self.throttle = throttle

    def neutral(self):
        self.neutral_calls += 1
        self.throttle = 0.0


def records_of(tub):
    tub = Tub(tub)
    try:
        return list(tub)
    finally:
        tub.close()


def test_rollout_records_expert_labels_that_correct_the_pilot(car_cfg, tmp_path):
    pilot = Swerve()
    out = rollout(car_cfg, pilot, tmp_path / "data" / "r1", records=80, tracks=[3], draw=101, beta=0.0)
    recs = records_of(out["tub"])
    assert len(recs) == out["records"] == pilot.frames == 80
    assert all(r["user/correction"] is True and r["user/mode"] == "local" for r in recs)
    assert all(r["pilot/angle"] == -1.0 and r["pilot/throttle"] == 0.4 for r in recs)
    # the pilot swerves off the road; the expert's label steers back (right, positive), so they differ
    assert out["interventions"] >= 1
    labels = np.array([r["user/angle"] for r in recs])
    assert np.mean(labels > 0) > 0.5 and out["pilot_vs_expert_abs_angle"] > 0.5
    assert all(-1.0 <= r["user/throttle"] <= 1.0 for r in recs)
    assert {r["sim/track"] for r in recs} == {3}


def test_beta_mixing_lets_the_expert_drive_that_share_of_frames():
    lab = Labeller(beta=0.5, seed=3)
    modes = [lab.run(0.2, 0.5, -0.1) for _ in range(2000)]
    expert = [m for m in modes if m[0] == "user"]
    assert 0.45 < len(expert) / 2000 < 0.55 and lab.expert_frames == len(expert)
    assert all(m[3] is False for m in expert) and all(m[3] is True for m in modes if m[0] == "local")
    assert all(m[1:3] == (0.2, 0.5) for m in modes)  # the label is the expert's whoever drives
    assert lab.mean_abs_error == pytest.approx(0.3)
    assert DaggerPlan(rounds=3, beta=0.8).beta_of(3) == pytest.approx(0.2)


def test_each_round_drives_whole_stretches_of_a_few_tracks_in_turn():
    plan = DaggerPlan(rounds=3, records=600, tracks=list(range(1, 8)))
    assert [plan.tracks_of(i) for i in (1, 2, 3)] == [[1, 2, 3], [4, 5, 6], [7, 1, 2]]  # 200 frames per track
    assert DaggerPlan(rounds=1, records=50, tracks=[5, 6]).tracks_of(1) == [5]


def test_one_round_writes_a_correction_tub_a_fine_tuned_model_and_the_round_table(car_cfg, make_model_file,
                                                                                  tmp_path, torch_one_thread):
    start = make_model_file("linear", name="start")
    plan = DaggerPlan(rounds=1, records=60, tracks=[3, 4], eval_tracks=[101], eval_draws=1, eval_themes=["road"],
                      laps=1, max_time=2.0)
    said = []
    result = run_dagger(car_cfg, [], tmp_path / "models" / "dg.pt", plan, start_model=start,
                        train_options={"register": False}, say=said.append)
    rounds = result["rounds"]
    assert [r["round"] for r in rounds] == [0, 1]
    assert result["model"] == tmp_path / "models" / "dg_r1.pt" and result["model"].exists()
    tub = tmp_path / "data" / "dagger_dg_r1"
    recs = records_of(tub)
    assert len(recs) == 60 and all(r["user/correction"] for r in recs)
    assert rounds[1]["rollout"]["records"] == 60 and rounds[1]["rollout"]["draw"] == 101
    for r in rounds:
        s = r["by_theme"]["road"]
        assert s["draws"] == [1001] and len(s["per_draw"]) == 1
        assert s["expert_speed"] > 0  # round 0's expert reference carried into round 1
    table = json.loads((tmp_path / "models" / "dg.dagger.json").read_text())
    assert [r["round"] for r in table["rounds"]] == [0, 1] and table["draws"] == [1001]
    text = format_rounds(rounds)
    assert text.splitlines()[0].split()[:2] == ["round", "theme"] and len(text.splitlines()) == 4


def test_ctrl_c_keeps_finished_rounds_and_leaves_the_throttle_at_neutral(car_cfg, make_model_file, tmp_path,
                                                                         monkeypatch):
    import vehicle.app.evaluate as ev

    start = make_model_file("linear", name="start")
    real = ev.resolve_pilot
    pilot = Swerve(interrupt_at=30)
    monkeypatch.setattr(ev, "resolve_pilot", lambda p, cfg=None, sim="builtin": (
        (pilot, "swerve", False) if str(p).endswith("start.pt") and cfg is car_cfg else real(p, cfg, sim)))
    actuator = Actuator()
    plan = DaggerPlan(rounds=2, records=100, tracks=[3], eval_tracks=[101], eval_draws=1, eval_themes=["road"],
                      laps=1, max_time=2.0)
    with pytest.raises(KeyboardInterrupt):
        run_dagger(car_cfg, [], tmp_path / "models" / "dg.pt", plan, start_model=start,
                   train_options={"register": False}, say=lambda s: None, add_parts=lambda V: V.add(actuator))
    assert actuator.neutral_calls == 1 and actuator.throttle == 0.0
    table = json.loads((tmp_path / "models" / "dg.dagger.json").read_text())
    assert [r["round"] for r in table["rounds"]] == [0]  # round 0 finished; round 1 was cut short
    assert len(records_of(tmp_path / "data" / "dagger_dg_r1")) == 29  # the frames labelled before the 30th raised
    # run again into the same names: refused before any work, the kept round untouched
    with pytest.raises(ValueError, match="exist"):
        run_dagger(car_cfg, [], tmp_path / "models" / "dg.pt", plan, start_model=start, say=lambda s: None)
    assert len(records_of(tmp_path / "data" / "dagger_dg_r1")) == 29


def test_training_keeps_corrections_whatever_train_modes_says(tmp_path):
    from training.dataset import read_drive_data

    tub = Tub(tmp_path / "tub", inputs=["cam/image_array", "user/angle", "user/throttle", "user/mode",
                                        "user/correction"],
              types=["image_array", "float", "float", "str", "boolean"])
    img = np.zeros((120, 160, 3), np.uint8)
    for mode, correction in [("user", None), ("local", True), ("local", False), ("local", None)]:
        rec = {"cam/image_array": img, "user/angle": 0.1, "user/throttle": 0.2, "user/mode": mode}
        if correction is not None:
            rec["user/correction"] = correction
        tub.write_record(rec)
    tub.close()
    data = read_drive_data([tmp_path / "tub"], modes=["user"])
    assert [(r.data["user/mode"], r.data.get("user/correction")) for r in data.records] == [
        ("user", None), ("local", True)]


@pytest.mark.parametrize("args, message", [
    (["--dagger", "0"], "--dagger 0: give at least 1 round"),
    (["--dagger", "1", "--dagger-tracks", "1-x"], "--dagger-tracks 1-x: give track seeds"),
    (["--dagger", "1", "--dagger-tracks", "100-102", "--eval-tracks", "101"], "also evaluation tracks"),
    (["--dagger", "1", "--eval-themes", "moon"], "unknown theme 'moon'"),
    (["--dagger", "1", "--dagger-beta", "1.5"], "--dagger-beta 1.5"),
])
def test_dagger_options_are_checked_before_any_work(tmp_path, capsys, make_model_file, args, message):
    from vehicle.app.cli import main
    from vehicle.app.commands.train import seed_list

    assert seed_list("1-3,7", "--x") == [1, 2, 3, 7]
    start = make_model_file("linear", name="start")
    assert main(["train", "--car", str(tmp_path), "--transfer", str(start), *args]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "data").exists()  # nothing recorded


def test_ctrl_c_in_a_rounds_training_says_dagger_ends_not_the_demo(car_cfg, make_model_file, tmp_path, monkeypatch,
                                                                    capsys):
    import training.trainer

    start = make_model_file("linear", name="start")
    monkeypatch.setattr(training.trainer, "train", lambda *a, **k: {  # Ctrl-C during round 1's fine-tuning
        "cancelled": True, "best_val_loss": 0.01, "best_epoch": 1, "epochs": 1})
    plan = DaggerPlan(rounds=1, records=20, tracks=[3], eval_tracks=[101], eval_draws=1, eval_themes=["road"],
                      laps=1, max_time=1.0)
    with pytest.raises(KeyboardInterrupt):
        run_dagger(car_cfg, [], tmp_path / "models" / "dg.pt", plan, start_model=start,
                   train_options={"register": False}, say=lambda s: None)
    out = capsys.readouterr().out
    assert "stopped by Ctrl-C in epoch 1" in out and "DAgger ends here" in out and "demo" not in out


def test_the_round_table_shows_score_laps_and_driven_share_beside_autonomy():
    """Item 22: a round whose pilot stood still in a draw (autonomy 100 %, none of its laps) reads
    score 0 and 0 % driven there, not as if it drove."""
    import re

    from vehicle.app.eval_draws import summarise

    still = {"autonomy": 100.0, "interventions": 0, "laps_completed": 0, "mean_abs_cte": 0.01, "mean_speed": 0.0,
             "completion": 0.0, "score": 0.0}
    drove = {"autonomy": 90.0, "interventions": 1, "laps_completed": 2, "mean_abs_cte": 0.08, "mean_speed": 1.2,
             "completion": 1.0, "score": 90.0}
    rounds = [{"round": 0, "by_theme": {"road": summarise([still, still], [1001, 1002])}, "rollout": None},
              {"round": 1, "by_theme": {"road": summarise([drove, still], [1001, 1002])},
               "rollout": {"records": 60, "pilot_vs_expert_abs_angle": 0.123}}]
    header, _rule, *rows = format_rounds(rounds).splitlines()
    columns = re.split(r"\s{2,}", header.strip())
    table = [dict(zip(columns, re.split(r"\s{2,}", r.strip()), strict=True)) for r in rows]
    assert columns[:8] == ["round", "theme", "score mean", "worst (draw)", "driven % mean", "laps mean",
                           "autonomy % mean", "worst"]
    assert [(r["score mean"], r["worst (draw)"], r["driven % mean"], r["laps mean"], r["autonomy % mean"])
            for r in table] == [("0.0", "0.0 (1001)", "0", "0.0", "100.0"), ("45.0", "0.0 (1002)", "50", "1.0", "95.0")]
    assert table[1]["new records"] == "60" and table[1]["pilot-expert |angle|"] == "0.123"
