"""``vehicle sim robustness --lanes``: the lanes demo's two models over seeds x precisions x hidden
draws, reported per model, resumed; each failed change located and shown in its run's gallery."""

from __future__ import annotations

import json

import pytest

from vehicle.app.cli import main
from vehicle.app.lanes_robustness import aggregate_lanes, lanes_tables


@pytest.mark.slow
def test_tiny_lanes_protocol_reports_per_model_and_resumes(tmp_path, capsys):
    out = tmp_path / "rb"
    args = ["sim", "robustness", "--lanes", "--records", "300", "--lane-changes", "2", "--epochs", "1",
            "--train-tracks", "1", "--eval-tracks", "101", "--laps", "1", "--draws", "1", "--seeds", "2",
            "--precisions", "fp32", "--jobs", "1", "--out", str(out)]
    assert main(args) == 0
    assert "run lanes-s2-fp32: finished in" in capsys.readouterr().out
    report = json.loads((out / "robustness.json").read_text())
    assert report["command"].startswith("vehicle sim robustness --lanes --seeds 2 --precisions fp32 --draws 1")
    assert "--lane-changes 2" in report["command"] and report["failed"] == []
    run = out / "runs" / "lanes-s2-fp32"
    result = json.loads((run / "eval" / "result.json").read_text())
    # --seed 2 as the plain demo's: TRAIN_SEED 43, the recording's SIM_SEED 10000; evaluated as asked
    assert (result["seed"], result["precision"], result["train_seed"], result["sim_seed"]) == (2, "fp32", 43, 10000)
    assert "TRAIN_SEED = 43" in (run / "myconfig.py").read_text()
    assert (result["draws"], result["themes"], result["eval_tracks"]) == ([1001], ["road"], [101])
    assert set(report["models"]) == {"lanes", "behavior"} and report["themes"] == ["road"]
    for model in ("lanes", "behavior"):
        mine = result["models"][model]
        road = report["models"][model]["themes"]["road"]
        draw = mine["by_theme"]["road"]["per_draw"][0]["lanes"]
        assert (road["runs"], road["draws"]) == (1, 1)
        assert (road["lane_changes"], road["lane_changes_ok"]) == (draw["lane_changes"], draw["lane_changes_ok"])
        assert road["off_track_events"]["total"] == draw["off_track_events"]
        assert road["worst_draw"]["randomize"] == 1001 and road["worst_seed"]["seed"] == 2
        assert report["models"][model]["plain"]["lane_changes"] == mine["plain"]["lane_changes"] >= 1
        # each failed change under the draw: located, and a moment of the worst draw's gallery
        failed = [f for f in mine["failed_changes"] if f["randomize"] == 1001]
        assert road["failed_changes"]["total"] == len(failed) >= 1  # 1 epoch on 300 records: it fails
        page = road["worst_draw"]["gallery"]
        assert page == f"runs/lanes-s2-fp32/eval/gallery/{model}/road-draw1001/index.html"
        gallery = json.loads((out / page).with_name("gallery.json").read_text())
        shown = [m["command"] for t in gallery["tracks"] for m in t["moments"] if m["kind"] == "failed_change"]
        assert shown == [{k: v for k, v in f.items() if k not in ("track", "theme", "randomize")} for f in failed]
        assert all(f["start_lane"] and f["curvature_1pm"] is not None and "expert_would_wait" in f for f in failed)
    md = (out / "robustness.md").read_text()
    assert "# Robustness of the lanes demo's models" in md and "| lanes | road | 1 x 1 |" in md
    assert "| behavior | road | 1 x 1 |" in md and "Failed changes" in md and "lanes-s2-fp32 behavior, road draw" in md

    # again: nothing is redone
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "run lanes-s2-fp32: finished before" in printed and "started" not in printed
    assert json.loads((out / "robustness.json").read_text())["runs_kept"] == 1


def _draw(ok: int, n: int, off: int, wrong: float = 0.0, t: float = 2.0) -> dict:
    return {"lane_changes": n, "lane_changes_ok": ok, "lane_change_success_rate": round(ok / n, 3),
            "mean_time_to_change_s": t, "max_time_to_change_s": t + 1, "wrong_lane_s": wrong, "off_track_events": off}


def _failed(wait: bool, failure: str, draw: int | None = 1001) -> dict:
    return {"track": 101, "theme": "road", "randomize": draw, "time_s": 12.0, "lane": "Left_Lane", "success": False,
            "curvature_1pm": 0.6 if wait else 0.1, "start_lane": "right", "expert_would_wait": wait,
            "failure": failure, "failed_at_s": 13.5}


def _lanes_result(seed: int, precision: str, draws: dict[str, list[dict]], failed: dict[str, list[dict]]) -> dict:
    """A ``vehicle demo --lanes`` summary: per model its hidden draws' lane figures (road theme)."""
    models = {}
    for m, rows in draws.items():
        plain = {**_draw(4, 4, 0), "interventions": 0}
        models[m] = {"metrics": {"best_val_loss": 0.02}, "plain": plain, "failed_changes": failed.get(m, []),
                     "by_theme": {"road": {"per_draw": [{"randomize": 1001 + i, "interventions": d["off_track_events"],
                                                         "lanes": d} for i, d in enumerate(rows)]}}}
    return {"name": f"lanes-s{seed}-{precision}", "seed": seed, "precision": precision, "themes": ["road"],
            "models": models, "seconds": {"record": 1.0, "train lanes": 2.0, "train behavior": 1.5, "evaluate": 3.0}}


def test_lanes_report_gives_each_model_its_worst_draw_worst_seed_and_failures():
    results = [
        _lanes_result(1, "fp32", {"lanes": [_draw(4, 4, 0), _draw(4, 4, 0, t=3.0)],
                                  "behavior": [_draw(4, 4, 0), _draw(3, 4, 0, wrong=1.5)]},
                      {"behavior": [_failed(True, "too_slow")]}),
        _lanes_result(2, "fp32", {"lanes": [_draw(4, 4, 0), _draw(4, 4, 0)],
                                  "behavior": [_draw(2, 4, 2), _draw(4, 4, 0)]},
                      {"behavior": [_failed(True, "off_road"), _failed(False, "off_road"),
                                    _failed(False, "too_slow", draw=None)]}),
    ]
    report = aggregate_lanes(results)
    lanes, behavior = report["models"]["lanes"]["themes"]["road"], report["models"]["behavior"]["themes"]["road"]
    assert (lanes["lane_changes_ok"], lanes["lane_changes"], lanes["success_rate_mean"]) == (16, 16, 1.0)
    assert lanes["time_to_change_s"] == {"mean": 2.25, "max": 4.0}
    assert lanes["off_track_events"] == {"total": 0, "max_per_draw": 0}
    # behavior: draws 100 %, 75 %, 50 % (2 off-track), 100 %: the worst draw is seed 2's first
    assert behavior["success_rate_mean"] == pytest.approx(0.812, abs=1e-3)
    assert behavior["worst_draw"] == {"run": "lanes-s2-fp32", "seed": 2, "precision": "fp32", "randomize": 1001,
                                      "lane_change_success_rate": 0.5, "lane_changes": 4, "lane_changes_ok": 2,
                                      "off_track_events": 2, "wrong_lane_s": 0.0}
    # seed 1: 7 of 8, seed 2: 6 of 8
    assert behavior["worst_seed"]["seed"] == 2 and behavior["worst_seed"]["lane_change_success_rate"] == 0.75
    assert behavior["wrong_lane_s"] == {"mean_per_draw": 0.375, "max_per_draw": 1.5}
    # the failure in the demo's own look (draw None) is not one of the hidden draws'
    assert behavior["failed_changes"] == {"total": 3, "expert_would_wait": 2, "off_road": 2}
    assert report["models"]["behavior"]["plain"] == {"lane_changes": 8, "lane_changes_ok": 8, "off_track_events": 0,
                                                     "runs_meeting_claim": 2}
    assert len(report["failed_changes"]) == 4 and {f["run"] for f in report["failed_changes"]} == {
        "lanes-s1-fp32", "lanes-s2-fp32"}
    for m in report["models"].values():  # no gallery pages exist here
        m["themes"]["road"]["worst_draw"]["gallery"] = None
    md = "\n".join(lanes_tables(report))
    # every lanes draw succeeded: the worst is the slowest (seed 1's second draw, changes up to 4 s)
    assert "| lanes | road | 2 x 2 | 16/16 | 100 | 100, 0 (s1, fp32, 1002) | 100 (s1, fp32) | 2.25 / 4.00 |" in md
    assert "| behavior | road | 2 x 2 | 13/16 | 81 | 50, 2 (s2, fp32, 1001) | 75 (s2, fp32) |" in md
    assert "| 2 of 3 / 2 of 3 |" in md and "| behavior | 8/8 | 0 | 2 of 2 |" in md
    assert ("- lanes-s2-fp32 behavior, road draw 1001, track 101: to Left_Lane at 12.0 s from the right lane, "
            "curvature ahead 0.60 1/m (the expert would have waited); left the road at 13.5 s") in md
    assert "| lanes-s1-fp32 | 1 | fp32 | lanes | 0.02000 | 4/4, 0 | 1 | 2 | 3 |" in md
    assert "lanes-s2-fp32 behavior, road draw none, track 101" in md


@pytest.mark.parametrize("args, message", [
    (["--lanes", "--recipe", "robust"], "--recipe chooses the plain demo's recipe: leave it out with --lanes"),
    (["--lane-changes", "3"], "--lane-changes belongs to --lanes"),
    (["--lanes", "--lane-changes", "0"], "--lane-changes 0: give at least 1"),
    (["--lanes", "--eval-tracks", "8,101"], "--eval-tracks: 8 are training tracks"),
])
def test_lanes_protocol_refuses_bad_options_in_one_line(tmp_path, capsys, args, message):
    assert main(["sim", "robustness", "--out", str(tmp_path / "rb"), "--precisions", "fp32", *args]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "rb").exists()
