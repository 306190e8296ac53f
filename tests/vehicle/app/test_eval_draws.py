"""Evaluation over hidden randomisation draws: mean and worst draw per theme, reproducible."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from vehicle.app.cli import main
from vehicle.app.eval_draws import evaluate_draws, format_draws_table, hidden_draws, summarise


class Squint:
    """A pilot whose steering follows the image's brightness, so another light gives another drive."""

    def run(self, image):
        left, right = image[60:, :80].mean(), image[60:, 80:].mean()
        return float(np.clip((right - left) / 20.0, -1, 1)), 0.35


def test_summary_mean_and_worst_draw():
    overalls = [
        {"autonomy": 100.0, "interventions": 0, "laps_completed": 2, "mean_abs_cte": 0.05, "mean_speed": 1.5,
         "off_track_per_lap": 0.0},
        {"autonomy": 88.0, "interventions": 2, "laps_completed": 2, "mean_abs_cte": 0.08, "mean_speed": 1.2,
         "off_track_per_lap": 1.0},
        {"autonomy": 88.0, "interventions": 2, "laps_completed": 2, "mean_abs_cte": 0.09, "mean_speed": 1.3,
         "off_track_per_lap": 1.0},
    ]
    expert = [{"autonomy": 100.0, "mean_speed": 2.0}] * 3
    s = summarise(overalls, [1001, 1002, 1003], expert)
    assert s["mean"]["autonomy"] == pytest.approx(92.0) and s["mean"]["interventions"] == pytest.approx(4 / 3, abs=1e-4)
    assert s["mean"]["mean_speed"] == pytest.approx(4.0 / 3, abs=1e-4)
    # equal autonomy and interventions: the larger mean |CTE| is the worse draw
    assert s["worst"]["randomize"] == 1003 and s["worst"]["autonomy"] == 88.0 and s["worst"]["laps_completed"] == 2
    assert s["expert_speed"] == 2.0 and s["speed_vs_expert_pct"] == pytest.approx(66.7)
    assert [d["randomize"] for d in s["per_draw"]] == [1001, 1002, 1003]
    # a draw where the car stood still (no intervention, 100 % autonomy) is the worst of all
    still = {**overalls[0], "laps_completed": 0, "completion": 0.0, "score": 0.0}
    with_still = summarise([*overalls, still], [1001, 1002, 1003, 1004])
    assert with_still["worst"]["randomize"] == 1004 and with_still["worst"]["score"] == 0.0
    assert with_still["per_draw"][3]["completion"] == 0.0  # the share of laps driven stays beside autonomy


def test_hidden_draws_are_fixed_and_never_the_training_draw():
    assert hidden_draws(3) == hidden_draws(3, training_draw=1) == [1001, 1002, 1003]
    with pytest.raises(ValueError, match="SIM_RANDOMIZE"):
        hidden_draws(3, training_draw=1002)
    with pytest.raises(ValueError, match=">= 1"):
        hidden_draws(0)


def test_draws_differ_and_a_rerun_is_identical(cfg):
    report = evaluate_draws(Squint(), [101], 1, cfg=cfg, draws=[1001, 1002], themes=["park"], max_time=3.0)
    assert [(t["theme"], t["randomize"]) for t in report["tracks"]] == [("park", 1001), ("park", 1002)]
    for theme in ("park",):
        s = report["by_theme"][theme]
        per = s["per_draw"]
        assert per[0]["mean_abs_cte"] != per[1]["mean_abs_cte"]  # another draw, another drive
        assert s["mean"]["mean_abs_cte"] == pytest.approx(np.mean([p["mean_abs_cte"] for p in per]), abs=1e-4)
        worst = min(per, key=lambda p: (p["score"], -p["interventions"], -p["mean_abs_cte"]))  # as worst_index
        assert s["worst"]["randomize"] == worst["randomize"]
        assert s["expert_speed"] > 0
    again = evaluate_draws(Squint(), [101], 1, cfg=cfg, draws=[1002], themes=["park"], max_time=3.0, expert=False)
    assert again["by_theme"]["park"]["per_draw"][0] == report["by_theme"]["park"]["per_draw"][1]  # reproducible
    table = format_draws_table(report).splitlines()
    assert table[0].split()[0] == "theme" and table[2].split()[0] == "park"


def test_cli_draws_writes_the_table_and_json(tmp_path, capsys):
    out = tmp_path / "draws.json"
    rc = main(["sim", "eval", "--car", str(tmp_path), "--pilot", "expert", "--tracks", "101", "--laps", "1",
               "--max-time", "3", "--theme", "road,park", "--draws", "2", "--json", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "2 hidden randomisation draw(s) (1001, 1002) per theme" in text
    report = json.loads(out.read_text())
    assert set(report["by_theme"]) == {"road", "park"} and report["draws"] == [1001, 1002]
    assert len(report["tracks"]) == 4 and report["overall"]["tracks"] == 4
    assert main(["sim", "eval", "--car", str(tmp_path), "--pilot", "expert", "--draws", "1", "--randomize", "3"]) == 2


def _cells(line):
    """A table row's cells (columns are right-justified and two spaces apart)."""
    return re.split(r"\s{2,}", line.strip())


STILL = {"autonomy": 100.0, "interventions": 0, "laps_completed": 0, "mean_abs_cte": 0.01, "mean_speed": 0.0,
         "off_track_per_lap": None, "completion": 0.0, "score": 0.0}
DROVE = {"autonomy": 90.0, "interventions": 1, "laps_completed": 1, "mean_abs_cte": 0.08, "mean_speed": 1.2,
         "off_track_per_lap": 1.0, "completion": 1.0, "score": 90.0}


def test_the_draws_table_shows_score_and_driven_share_and_names_the_worst_by_score():
    """Item 22: a draw where the car stood still (autonomy 100 %, none of its laps) shows score 0 and
    0 % driven, and the footer says the worst draw is the lowest score (it is picked so)."""
    report = {"by_theme": {"park": summarise([DROVE, STILL], [1001, 1002])}, "draws": [1001, 1002],
              "pilot": "p.pt", "seeds": [101], "laps": 1}
    header, _rule, row, footer = format_draws_table(report).splitlines()
    columns, values = _cells(header), _cells(row)
    assert columns[:7] == ["theme", "score mean", "worst (draw)", "driven % mean", "worst", "autonomy % mean",
                           "worst"]
    assert values[:7] == ["park", "45.0", "0.0 (1002)", "50", "0", "95.0", "100.0"]
    assert len(values) == len(columns)
    assert footer.endswith("worst = the draw with the lowest score (autonomy x share of the laps driven)")
    assert "lowest autonomy" not in footer
