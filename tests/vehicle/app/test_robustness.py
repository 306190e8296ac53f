"""``vehicle sim robustness``: runs of the demo over seeds x precisions, resumed after a kill,
aggregated into mean, worst draw and worst seed per theme."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from vehicle.app import robustness
from vehicle.app.cli import main
from vehicle.app.eval_draws import summarise

THEMES = ["road", "indoor", "park"]


def test_tiny_protocol_runs_the_demo_per_seed_reports_and_resumes(tmp_path, capsys):
    out = tmp_path / "rb"
    args = ["sim", "robustness", "--records", "200", "--epochs", "1", "--train-tracks", "1,2", "--eval-tracks",
            "101", "--laps", "1", "--draws", "1", "--seeds", "1,2", "--precisions", "fp32", "--jobs", "2",
            "--out", str(out)]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "run plain-s1-fp32: finished in" in printed and "run plain-s2-fp32: finished in" in printed
    report = json.loads((out / "robustness.json").read_text())
    assert report["command"].startswith("vehicle sim robustness --recipe plain --seeds 1,2 --precisions fp32")
    assert report["cpu"] and len(report["load_average"]["start"]) == 3 and report["wall_seconds"] > 0
    assert report["runs_seconds"] > 0
    assert (report["runs_done_now"], report["runs_kept"], report["failed"]) == (2, 0, [])
    assert list(report["themes"]) == THEMES and report["unseen_themes"] == ["park"]
    runs = {r["name"]: r for r in report["runs"]}
    assert set(runs) == {"plain-s1-fp32", "plain-s2-fp32"}
    for name, seed in (("plain-s1-fp32", 1), ("plain-s2-fp32", 2)):
        result = json.loads((out / "runs" / name / "eval" / "result.json").read_text())
        assert (result["seed"], result["precision"], result["train_seed"]) == (seed, "fp32", 41 + seed)
        assert result["recordings"][0]["draw"] == 1 + (seed - 1) * 10000  # another seed, other data
        assert runs[name]["best_val_loss"] == result["metrics"]["best_val_loss"] > 0
        assert set(runs[name]["seconds"]) == {"record", "train", "evaluate"}
        assert "demo finished in" in (out / "runs" / f"{name}.log").read_text()
    for theme in THEMES:
        s = report["themes"][theme]
        assert (s["runs"], s["draws"], s["laps_asked"]) == (2, 2, 2)  # 2 runs x 1 draw x 1 lap on 1 track
        assert s["worst_draw"]["randomize"] == 1001 and s["worst_draw"]["seed"] in (1, 2)
        # the theme's mean is the mean of the runs' own scores (one draw each), never above autonomy
        run_scores = [json.loads((out / "runs" / name / "eval" / "result.json").read_text())
                      ["by_theme"][theme]["mean"]["score"] for name in sorted(runs)]
        assert s["mean"]["score"] == pytest.approx(sum(run_scores) / 2, abs=0.01)
        assert s["mean"]["score"] <= s["mean"]["autonomy"] and s["speed_vs_expert_pct"] is not None
    md = (out / "robustness.md").read_text()
    assert "| park (unseen) | 2 x 1 |" in md and "| plain-s2-fp32 | 2 | fp32 |" in md
    for theme in THEMES:  # each theme's worst draw links its failure gallery, which the run wrote
        w = report["themes"][theme]["worst_draw"]
        assert w["gallery"] == f"runs/{w['run']}/eval/gallery/{theme}-draw1001/index.html"
        assert (out / w["gallery"]).is_file() and f"]({w['gallery']})" in md

    # again: nothing is redone
    mtimes = {p: p.stat().st_mtime_ns for p in (out / "runs").glob("*/eval/result.json")}
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert printed.count("finished before") == 2 and "started" not in printed
    assert {p: p.stat().st_mtime_ns for p in mtimes} == mtimes
    assert json.loads((out / "robustness.json").read_text())["runs_kept"] == 2


def _result(seed: int, precision: str, scores: dict[str, list[tuple[float, float]]]) -> dict:
    """A run's result.json: per theme, per draw (autonomy, share of the 2 laps asked driven)."""
    by_theme = {}
    for theme, draws in scores.items():
        overalls = [{"autonomy": a, "completion": c, "score": a * c, "laps_completed": int(2 * c),
                     "interventions": round((100 - a) / 10), "mean_abs_cte": 0.05, "mean_speed": 1.5 if c else None,
                     "off_track_per_lap": 0.0} for a, c in draws]
        by_theme[theme] = summarise(overalls, [1001 + i for i in range(len(draws))],
                                    [{"autonomy": 100.0, "mean_speed": 1.5}] * len(draws))
    return {"name": f"plain-s{seed}-{precision}", "seed": seed, "precision": precision, "laps": 2,
            "eval_tracks": [101], "trained_themes": ["road"], "unseen_theme": "park", "by_theme": by_theme,
            "seconds": {"record": 1.0, "train": 2.0, "export": 0.1, "evaluate": 3.0},
            "metrics": {"best_val_loss": 0.01}}


def test_a_run_whose_car_stood_still_is_the_worst_and_does_not_lift_the_mean():
    results = [
        _result(1, "fp32", {"road": [(100.0, 1.0), (90.0, 1.0)], "park": [(80.0, 1.0), (70.0, 1.0)]}),
        # stood still in park: no intervention, 100 % DAVE-2 autonomy, no lap driven
        _result(2, "fp32", {"road": [(100.0, 1.0), (100.0, 1.0)], "park": [(100.0, 0.0), (60.0, 1.0)]}),
        _result(1, "bf16", {"road": [(100.0, 1.0), (80.0, 1.0)], "park": [(90.0, 1.0), (90.0, 1.0)]}),
    ]
    report = robustness.aggregate(results)
    park, road = report["themes"]["park"], report["themes"]["road"]
    assert list(report["themes"]) == ["road", "park"] and report["unseen_themes"] == ["park"]
    assert park["worst_draw"] == {"run": "plain-s2-fp32", "seed": 2, "precision": "fp32", "randomize": 1001,
                                  "score": 0.0, "autonomy": 100.0, "completion": 0.0, "laps_completed": 0,
                                  "laps_asked": 2, "interventions": 0}
    assert park["worst_seed"]["seed"] == 2 and park["worst_seed"]["score"] == pytest.approx(30.0)
    # the still car's 100 % counts 0 in the score mean: (80 + 70 + 0 + 60 + 90 + 90) / 6
    assert park["mean"]["score"] == pytest.approx(65.0) and park["mean"]["autonomy"] == pytest.approx(81.667)
    assert park["mean"]["completion"] == pytest.approx(0.833, abs=1e-3)
    assert (park["laps_completed"], park["laps_asked"], park["incomplete_draws"]) == (10, 12, 1)
    # interventions per run over its draws: 2 + 3, 0 + 4, 1 + 1
    assert park["interventions"] == {"mean_per_run": pytest.approx(3.667, abs=1e-3), "max_per_run": 5}
    assert (road["worst_draw"]["seed"], road["worst_draw"]["precision"], road["worst_draw"]["randomize"],
            road["worst_draw"]["score"]) == (1, "bf16", 1002, 80.0)
    # mean scores 95 (s1 fp32), 100 (s2 fp32), 90 (s1 bf16): the worst seed is a precision path too
    assert road["worst_seed"] == {"seed": 1, "precision": "bf16", "score": 90.0, "autonomy": 90.0,
                                  "completion": 1.0}
    rows = {r["name"]: r for r in report["runs"]}
    assert rows["plain-s2-fp32"]["themes"]["park"]["worst"]["score"] == 0.0
    assert rows["plain-s1-bf16"]["seconds"] == {"record": 1.0, "train": 2.0, "evaluate": 3.0}
    md = robustness.format_markdown({**report, "recipe": "plain", "command": "vehicle sim robustness",
                                     "cpu": "X", "cores": 2, "load_average": {"start": [1, 1, 1], "end": [2, 2, 2]},
                                     "wall_seconds": 10, "runs_seconds": 30, "runs_done_now": 3, "runs_kept": 0,
                                     "draws": 2, "eval_tracks": [101], "failed": []})
    assert ("| park (unseen) | 3 x 2 | 65.0 | 81.7 | 10/12 (83 %, 1 draws incomplete) | "
            "0.0, 100.0 % (s2, fp32, 1001) |") in md


FAKE_DEMO = textwrap.dedent("""
    import json, signal, sys, time
    from pathlib import Path
    out = Path(sys.argv[1]); seed = int(sys.argv[2])
    (out / "eval").mkdir(parents=True, exist_ok=True)
    (out / "started").write_text("yes")
    def stopped(signum, frame):
        (out / "stopped").write_text(str(signum)); sys.exit(130)
    signal.signal(signal.SIGINT, stopped)
    time.sleep(float(sys.argv[3]))
    (out / "eval" / "result.json").write_text(json.dumps(json.loads(sys.argv[4])))
""")


def _fake_command(sleep_by_seed: dict[int, float]):
    def command(spec, folder, protocol):
        result = _result(spec.seed, spec.precision, {"road": [(100.0, 1.0)], "park": [(90.0, 1.0)]})
        return [sys.executable, "-c", FAKE_DEMO, str(folder), str(spec.seed), str(sleep_by_seed[spec.seed]),
                json.dumps(result)]
    return command


def test_an_unfinished_run_is_redone_and_a_finished_one_kept(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(robustness, "demo_command", _fake_command({1: 0.0, 2: 0.0}))
    out = tmp_path / "rb"
    (out / "runs" / "plain-s2-fp32" / "eval").mkdir(parents=True)  # killed before: no result.json
    (out / "runs" / "plain-s2-fp32" / "half.tub").write_text("x")
    protocol = robustness.Protocol(out=out, seeds=[1, 2], precisions=["fp32"], draws=1, jobs=2)
    assert robustness.run_protocol(protocol) == 0
    printed = capsys.readouterr().out
    assert "run plain-s2-fp32: unfinished before, removed and run again" in printed
    assert not (out / "runs" / "plain-s2-fp32" / "half.tub").exists()
    assert (out / "runs" / "plain-s2-fp32" / "eval" / "result.json").is_file()
    (out / "runs" / "plain-s1-fp32" / "eval" / "result.json").unlink()  # as if killed at the very end
    kept = (out / "runs" / "plain-s2-fp32" / "started").stat().st_mtime_ns
    assert robustness.run_protocol(protocol) == 0
    printed = capsys.readouterr().out
    assert "run plain-s2-fp32: finished before" in printed and "run plain-s1-fp32: started" in printed
    assert "plain-s2-fp32: started" not in printed
    assert (out / "runs" / "plain-s2-fp32" / "started").stat().st_mtime_ns == kept
    assert json.loads((out / "robustness.json").read_text())["runs_done_now"] == 1


def test_sigterm_stops_the_runs_through_their_ctrl_c_and_keeps_finished_ones(tmp_path):
    out = tmp_path / "rb"
    script = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_robustness import _fake_command
        from vehicle.app import robustness
        robustness.demo_command = _fake_command({{1: 0.0, 2: 60.0}})
        from vehicle.app.cli import main
        sys.exit(main(["sim", "robustness", "--seeds", "1,2", "--precisions", "fp32", "--draws", "1",
                       "--jobs", "2", "--out", {str(out)!r}]))
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], env=dict(os.environ), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT)
    slow = out / "runs" / "plain-s2-fp32"
    end = time.monotonic() + 60
    while not ((slow / "started").exists() and (out / "runs" / "plain-s1-fp32" / "eval" / "result.json").exists()):
        assert time.monotonic() < end and proc.poll() is None, proc.stdout.read().decode()
        time.sleep(0.05)
    time.sleep(0.3)  # the parent has seen the first run end
    proc.send_signal(signal.SIGTERM)
    printed = proc.communicate(timeout=60)[0].decode()
    assert proc.returncode == 143, printed
    assert (slow / "stopped").read_text() == str(int(signal.SIGINT))  # its own Ctrl-C path ran
    assert not (slow / "eval" / "result.json").exists() and "run plain-s2-fp32: stopping" in printed
    assert (out / "runs" / "plain-s1-fp32" / "eval" / "result.json").is_file()  # kept for the next call


@pytest.mark.parametrize("args, message", [
    (["--precisions", "fp16"], "--precisions fp16: give fp32, bf16 or fp32,bf16"),
    (["--seeds", "0,1"], "--seeds 0,1: give different seeds of 1 .. 100000"),
    (["--seeds", "1,1"], "--seeds 1,1: give different seeds"),
    (["--draws", "0"], "--draws 0: give at least 1"),
    (["--jobs", "0"], "--jobs 0: give at least 1"),
    (["--eval-tracks", "3,101"], "--eval-tracks: 3 are training tracks"),
])
def test_robustness_refuses_bad_options_in_one_line(tmp_path, capsys, args, message):
    assert main(["sim", "robustness", "--out", str(tmp_path / "rb"), "--precisions", "fp32", *args]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "rb").exists()


def test_bf16_is_refused_by_default_off_on_a_cpu_without_native_bf16(tmp_path, monkeypatch, capsys):
    from training import acceleration

    monkeypatch.setattr(acceleration, "cpu_caps", lambda: acceleration.DeviceCaps("cpu", "Old CPU"))
    from vehicle.app.cli import build_parser
    from vehicle.app.commands.sim import robustness_protocol

    args = build_parser().parse_args(["sim", "robustness", "--out", str(tmp_path)])
    assert robustness_protocol(args).precisions == ["fp32"]  # the default leaves bf16 out
    assert main(["sim", "robustness", "--out", str(tmp_path), "--precisions", "fp32,bf16"]) == 2
    assert "--precisions bf16: this CPU (Old CPU) has no native bf16" in capsys.readouterr().err
