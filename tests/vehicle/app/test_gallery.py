"""Failure galleries of ``vehicle sim eval --gallery``: the moments, the pictures, the page, the errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from vehicle.app.failure_moments import GallerySpec, MomentRecorder


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory):
    """An untrained model driven at a fixed throttle on track 11 for 10 s (it leaves the road several
    times), with a gallery; (report, gallery JSON, folder)."""
    import torch

    from parts.pilots.modelfile import save_model
    from parts.pilots.models import create_model
    from parts.pilots.preprocess import Preprocess
    from vehicle.app.evaluate import evaluate
    from vehicle.config import Config

    tmp = tmp_path_factory.mktemp("gallery")
    torch.manual_seed(0)
    pre = Preprocess(crop=(40, 0, 0, 0), image_shape=(120, 160, 3))
    model = save_model(tmp / "wander.pt", create_model("linear", pre.output_shape((120, 160, 3))),
                       {"preprocess": pre.to_dict()})
    cfg = Config.defaults(SIM_TEXTURE_RES=0.02, SIM_REALTIME=False)
    folder = tmp / "gallery"
    report = evaluate(str(model), [11], laps=1, cfg=cfg, max_time=10.0, fixed_throttle=0.4,
                      gallery=GallerySpec(str(folder), "", window_s=1.0, frames=4, worst=2))
    return report, json.loads((folder / "gallery.json").read_text()), folder


def test_gallery_moments_match_the_interventions_one_to_one(evaluated):
    report, data, folder = evaluated
    track, shown = report["tracks"][0], data["tracks"][0]
    assert track["interventions"] >= 2  # the untrained pilot leaves the road: there is something to show
    interventions = [m for m in shown["moments"] if m["kind"] == "intervention"]
    assert len(interventions) == track["interventions"] == shown["interventions"]
    assert [m["pos"] for m in interventions] == track["off_track_at"]
    assert [m["number"] for m in shown["moments"]] == list(range(1, len(shown["moments"]) + 1))
    assert shown["seed"] == 11 and shown["theme"] == track["theme"] and "randomize" in shown
    assert report["gallery"] == str(folder / "index.html") and report["settings"]["gallery"] == str(folder.resolve())
    assert "_gallery" not in track  # the stored report keeps the metrics only


def test_gallery_frames_hold_the_seconds_before_with_both_steerings(evaluated):
    import cv2

    _, data, folder = evaluated
    times = [m["time_s"] for m in data["tracks"][0]["moments"] if m["kind"] == "intervention"]
    for m in data["tracks"][0]["moments"]:
        frames = m["frames"]
        assert len(frames) == 4 and frames[-1]["t"] == 0.0 and frames[0]["t"] >= -1.0
        assert [f["t"] for f in frames] == sorted(f["t"] for f in frames)
        for f in frames:
            assert -1 <= f["pilot"]["angle"] <= 1 and -1 <= f["expert"]["angle"] <= 1
            img = cv2.imread(str(folder / f["image"]))
            heat = cv2.imread(str(folder / f["saliency"]["camera"]))
            assert img.shape == heat.shape == (120, 160, 3)
            assert np.abs(img[:40].astype(int) - heat[:40]).mean() < 3  # no heat on the cropped sky
            assert np.abs(img[40:].astype(int) - heat[40:]).mean() > 3  # heat where the model looked
        if m["kind"] == "worst_cte":  # on the road, and not in the window an intervention shows
            assert abs(m["cte"]) >= 0.05
            assert all(not t - 1.0 <= m["time_s"] <= t for t in times)
    # the expert knows the way back: it steers against the drift before the car leaves
    drifting = [m["frames"][-2] for m in data["tracks"][0]["moments"]
                if m["kind"] == "intervention" and abs(m["frames"][-2]["cte"]) > 0.2]
    assert drifting and all(np.sign(f["expert"]["angle"]) == -np.sign(f["cte"]) for f in drifting)


def test_gallery_page_is_static_and_complete(evaluated):
    _, data, folder = evaluated
    page = (folder / "index.html").read_text()
    assert "<script" not in page
    shown = data["tracks"][0]
    assert f"Track 11 · theme {shown['theme']}" in page
    for m in shown["moments"]:
        for f in m["frames"]:
            assert f'src="{f["image"]}"' in page and f'src="{f["saliency"]["camera"]}"' in page
    assert page.count("<section") == len(shown["moments"])


def test_recorder_keeps_worst_moments_apart_and_out_of_intervention_windows():
    rec = MomentRecorder(0.1, ("cam/image_array",), window_s=0.5, worst=2)
    frame = np.zeros((2, 2, 3), np.uint8)
    #        t: 0.1  0.2  0.3  0.4  0.5  0.6  0.7  0.8  0.9  1.0  1.1  1.2  1.3  1.4  1.5
    ctes = [0.10, 0.30, 0.20, 0.10, 0.10, 0.10, 0.25, 0.10, 0.10, 0.10, 0.10, 0.40, 0.50, 0.60, 0.00]
    offs = [False] * 14 + [True]
    for i, (c, off) in enumerate(zip(ctes, offs, strict=True)):
        rec.run(frame, 0.1, 0.2, -0.3, c, off, (float(i), 0.0))
    moments = rec.moments()
    assert [m.kind for m in moments] == ["intervention", "worst_cte", "worst_cte"]
    assert moments[0].time_s == pytest.approx(1.5) and moments[0].pos == [13.0, 0.0]  # the last position on road
    assert len(moments[0].steps) == 5 and moments[0].steps[0].time_s == pytest.approx(1.1)
    # 0.6 m at 1.4 s lies in the intervention's window; 0.30 (0.2 s) and 0.25 (0.7 s) are a window apart
    assert [(round(m.time_s, 1), m.cte) for m in moments[1:]] == [(0.2, 0.30), (0.7, 0.25)]


def test_gallery_errors_are_one_line_and_touch_nothing(make_model_file, tmp_path, capsys):
    from vehicle.app.cli import main

    model = make_model_file("linear")
    existing = tmp_path / "old"
    existing.mkdir()
    (existing / "keep.txt").write_text("mine")
    base = ["sim", "eval", "--tracks", "11", "--max-time", "1", "--no-store"]
    assert main([*base, "--pilot", str(model), "--gallery", str(existing)]) == 2
    err = capsys.readouterr().err.strip()
    assert f"gallery folder {existing} exists: give a new folder" in err and "\n" not in err
    assert [p.name for p in existing.iterdir()] == ["keep.txt"] and (existing / "keep.txt").read_text() == "mine"
    assert main([*base, "--pilot", "expert", "--gallery", str(tmp_path / "new")]) == 2
    assert "give --pilot a model file" in capsys.readouterr().err
    assert main([*base, "--pilot", str(model), "--gallery", str(tmp_path / "new"), "--gallery-frames", "0"]) == 2
    assert "gallery frames per moment 0: give 1 to 20" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()
    other = make_model_file("linear", name="udacity", frames=(160, 320))  # made for the Udacity simulator's frames
    assert main([*base, "--pilot", str(other), "--gallery", str(tmp_path / "new")]) == 2
    assert "160x320" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()


def test_draws_write_one_gallery_per_theme_and_draw_and_an_index(make_model_file, cfg, tmp_path):
    from vehicle.app.eval_draws import evaluate_draws

    model = make_model_file("linear")
    folder = tmp_path / "galleries"
    report = evaluate_draws(str(model), [11], 1, cfg=cfg, draws=[1001, 1002], themes=["indoor"], expert=False,
                            max_time=2.0, gallery=GallerySpec(str(folder), str(model), worst=1))
    index = json.loads((folder / "gallery.json").read_text())
    assert [g["folder"] for g in index["galleries"]] == ["indoor-draw1001", "indoor-draw1002"]
    for g, draw in zip(index["galleries"], (1001, 1002), strict=True):
        sub = json.loads((folder / g["folder"] / "gallery.json").read_text())
        assert sub["randomize"] == draw and sub["tracks"][0]["theme"] == "indoor"
        assert g["moments"] == sum(len(t["moments"]) for t in sub["tracks"])
        assert f'href="{g["folder"]}/index.html"' in (folder / "index.html").read_text()
    assert report["gallery"] == str(folder / "index.html") and report["settings"]["gallery"] == str(folder.resolve())
    with pytest.raises(ValueError, match="exists: give a new folder"):
        evaluate_draws(str(model), [11], 1, cfg=cfg, draws=[1001], themes=["indoor"], expert=False, max_time=1.0,
                       gallery=GallerySpec(str(folder), str(model)))


def test_recorder_keeps_each_failed_lane_change_from_before_its_command():
    """Issue 43: a failed commanded change is a gallery moment, judged by the lane metrics' own rule
    on the same steps, with the frames from ``window_s`` before the command to its failure."""
    from parts.sim.lane_metrics import LaneMetrics
    from vehicle.app.failure_moments import ChangeLimits, with_commands

    rec = MomentRecorder(0.1, ("cam/image_array",), window_s=0.5, worst=0, changes=ChangeLimits(0.4, 1.0, 0.3))
    lanes = LaneMetrics(0.1, 0.4, time_limit=1.0, hold=0.3)
    frame = np.zeros((2, 2, 3), np.uint8)
    for k in range(1, 71):
        t = k * 0.1
        # right lane at 1.0 s (done by 1.5 s); left at 3.0 s (the car stays: too slow); right at 5.0 s
        # (already there); left at 6.0 s, and the car leaves the road at 6.3 s
        center = 0.2 if t < 0.95 or 2.95 < t < 4.95 or t > 5.95 else -0.2
        lat = 0.2 if t < 0.95 else (max(-0.2, 0.2 - 0.08 * (k - 10)) if t < 2.95 else -0.2)
        off = 6.25 < t < 6.65
        rec.run(frame, 0.0, 0.3, 0.0, -lat, off, (t, 0.0), center)
        lanes.run(-lat, off, center, (t, 0.0), "Left_Lane" if center > 0 else "Right_Lane")
    result = lanes.result()
    failed = [c for c in result["commands"] if c["success"] is False]
    assert [(c["time_s"], c["failure"]) for c in failed] == [(3.0, "too_slow"), (6.0, "off_road")]
    assert result["lane_changes_ok"] == 2
    moments = with_commands(rec.moments(), result["commands"], 0.1)
    assert [m.kind for m in moments] == ["intervention", "failed_change", "failed_change"]
    first, second = moments[1:]
    assert (first.command_time_s, first.time_s, second.command_time_s, second.time_s) == pytest.approx(
        (3.0, 4.1, 6.0, 6.3))
    assert first.steps[0].time_s == pytest.approx(2.6) and first.steps[-1].time_s == pytest.approx(4.1)
    assert first.command is failed[0] and second.command is failed[1]


def test_a_lanes_pilot_gallery_shows_its_failed_changes_with_their_commands(make_model_file, tmp_path):
    from vehicle.app.evaluate import evaluate
    from vehicle.app.gallery import moment_title
    from vehicle.config import Config

    model = make_model_file("lanes", num_behaviors=2)
    cfg = Config.defaults(SIM_LANES=2, TRAIN_BEHAVIORS=True, SIM_TEXTURE_RES=0.02, SIM_REALTIME=False)
    folder = tmp_path / "gallery"
    report = evaluate(str(model), [101], laps=1, cfg=cfg, max_time=16.0, fixed_throttle=0.3, lane_changes=True,
                      gallery=GallerySpec(str(folder), "", window_s=1.0, frames=3, worst=0))
    failed = [c for c in report["tracks"][0]["lanes"]["commands"] if c["success"] is False]
    assert failed  # an untrained pilot fails its changes
    for c in failed:
        assert c["start_lane"] in ("left", "right", "off road") and c["curvature_1pm"] >= 0
        assert c["expert_would_wait"] == (c["curvature_1pm"] > cfg.SIM_EXPERT_LANE_CHANGE_MAX_CURVATURE)
    data = json.loads((folder / "gallery.json").read_text())
    shown = [m for m in data["tracks"][0]["moments"] if m["kind"] == "failed_change"]
    assert [m["command"] for m in shown] == failed  # one moment per failed command, carrying its record
    for m in shown:
        assert any(f["time_s"] == m["command_time_s"] for f in m["frames"])  # the frame the command came in
        assert m["frames"][-1]["time_s"] == m["time_s"] == m["command"]["failed_at_s"]
        assert f"commanded to {m['command']['lane']} at {m['command_time_s']:.1f} s from " in moment_title(m)
    assert "Failed lane change" in (folder / "index.html").read_text()
