"""Lane change on demand in the simulator: the expert follows behavior/state, changes lanes smoothly,
waits in tight corners; the behaviour schedule; the lane metrics."""

from __future__ import annotations

import numpy as np
import pytest

from parts.drive.behavior import BehaviorSchedule, BehaviorState, behavior_lane, random_change_times
from parts.sim.expert import Expert
from parts.sim.lane_metrics import LaneCommand, lane_metrics, overall_lane_metrics
from parts.sim.simulator import SimCar


@pytest.fixture
def lanes_cfg(cfg):
    return cfg.replace(SIM_LANES=2, TRAIN_BEHAVIORS=True, SIM_EXPERT_SPEED=1.5)


def _drive(cfg, seed: int, times: list[float], steps: int, initial: int = 1):
    sim = SimCar.from_config(cfg, seeds=[seed], reset_to="nearest")
    expert = Expert.from_config(cfg, sim)
    state = BehaviorState(cfg.BEHAVIOR_LIST, initial)
    schedule = BehaviorSchedule(times, sim.dt)
    rec = {"t": [], "lat": [], "cmd": [], "off": [], "curv": [], "state": []}
    commands = []
    for _ in range(steps):
        step = schedule.run()
        s, label, _ = state.run(step)
        if step:
            commands.append(LaneCommand(sim.time, sim.track.lane_offset(behavior_lane(label)), label))
        frame = sim.step(*expert.command(s))
        proj = sim.track.project((sim.car.state.x, sim.car.state.y))
        rec["t"].append(sim.time)
        rec["lat"].append(-frame.cte)
        rec["cmd"].append(sim.track.lane_offset(behavior_lane(label)))
        rec["off"].append(frame.off_track)
        rec["curv"].append(abs(sim.track.curvature[proj.index]))
        rec["state"].append(s)
    return sim, expert, {k: np.asarray(v) for k, v in rec.items()}, commands


def test_behaviour_names_give_lanes():
    assert [behavior_lane(n) for n in ("Left_Lane", "Right_Lane", "centre", "Stop")] == ["left", "right", "center",
                                                                                       None]
    with pytest.raises(ValueError, match="Left/Right"):
        Expert(SimCar([1], world={"res": 0.02, "lanes": 2}), behaviors=["Fast", "Slow"])


def test_expert_changes_lane_on_demand_smoothly_and_never_leaves_the_road(lanes_cfg):
    times = random_change_times(6, 75.0, seed=3)
    sim, expert, rec, commands = _drive(lanes_cfg, 2, times, 1600)
    assert expert.changes_started == 6 and len(commands) == 6
    assert sim.tracker.off_track_events == 0 and not rec["off"].any()
    width = sim.track.width / 2  # one lane
    m = lane_metrics(rec["t"], rec["lat"], rec["cmd"], rec["off"], width, commands)
    assert m["lane_changes"] == 6 and m["lane_change_success_rate"] == 1.0
    assert m["wrong_lane_s"] == 0.0 and m["lane_mean_abs_error"] < 0.03
    assert 0.5 < m["mean_time_to_change_s"] < 5.0
    # smooth: the lateral position never jumps, and the car crosses the centre line once per change
    assert np.abs(np.diff(rec["lat"])).max() < 0.05
    crossings = np.count_nonzero(np.diff(np.sign(rec["lat"])) != 0)
    assert crossings == 6


def test_expert_waits_for_a_straighter_road_in_tight_corners(lanes_cfg):
    sim = SimCar.from_config(lanes_cfg, seeds=[3])
    curv = np.abs(sim.track.curvature)
    # command a change just before the tightest corner of the track
    expert = Expert.from_config(lanes_cfg, sim)
    tight = int(np.argmax(curv))
    state = 1
    waited = None
    for _ in range(3000):
        s = sim.track.project((sim.car.state.x, sim.car.state.y)).index
        ahead = (tight - s) % sim.track.n * sim.track.length / sim.track.n
        if state == 1 and ahead < 0.5 and sim.time > 2:
            state = 0
            asked = sim.time
        sim.step(*expert.command(state))
        if state == 0 and waited is None and expert.changes_started:
            waited = sim.time - asked
            break
    assert waited is not None and expert.changes_delayed == 1
    assert 0.2 < waited <= lanes_cfg.SIM_EXPERT_LANE_CHANGE_MAX_DELAY + 0.1


def test_behaviour_schedule_and_random_times():
    times = random_change_times(5, 60.0, seed=1, min_gap=6.0, start=3.0)
    assert len(times) == 5 and times == sorted(times) and times[0] >= 3.0 and times[-1] <= 54.0
    assert min(np.diff(times)) >= 6.0 - 1e-9
    assert random_change_times(5, 60.0, seed=1) == times and random_change_times(5, 60.0, seed=2) != times
    with pytest.raises(ValueError, match="do not fit"):
        random_change_times(10, 30.0)
    sched = BehaviorSchedule([0.5, 1.0], dt=0.1)
    steps = [sched.run() for _ in range(20)]
    assert steps[4] == 1 and steps[9] == 1 and sum(steps) == 2


def test_lane_metrics_on_a_scripted_drive():
    dt = 0.1
    t = np.arange(0, 30, dt) + dt
    cmd = np.where(t < 10, 0.2, -0.2)
    lat = np.full(t.size, 0.2)
    # change 1 (t=10): reaches the right lane at t=12 and stays
    lat[t >= 10] = np.interp(t[t >= 10], [10, 12], [0.2, -0.2])
    # then from t=20 the command goes left again but the car stays right: a failed change
    cmd[t >= 20] = 0.2
    off = np.zeros(t.size, bool)
    commands = [LaneCommand(10.0, -0.2, "Right_Lane"), LaneCommand(20.0, 0.2, "Left_Lane")]
    m = lane_metrics(t, lat, cmd, off, 0.4, commands, time_limit=6.0, hold=1.0)
    first, second = m["commands"]
    # changed once the car's centre is within a quarter lane (0.1 m) of the right lane's centre:
    # from t = 11.5 s on
    assert first["success"] and first["time_to_change_s"] == pytest.approx(1.55, abs=0.06)
    assert second["success"] is False
    assert m["lane_changes"] == 2 and m["lane_change_success_rate"] == 0.5
    # after the failed change's window (20..26 s) the car is in the wrong lane until the end
    assert m["wrong_lane_s"] == pytest.approx(30 - 26, abs=2 * dt)
    assert m["off_track_events"] == 0
    # a change still being judged when the episode ends is not counted
    late = lane_metrics(t, lat, cmd, off, 0.4, [LaneCommand(29.5, 0.2)], time_limit=6.0)
    assert late["lane_changes"] == 0 and late["commands"][0]["success"] is None
    # leaving the road during a change fails it
    off2 = off.copy()
    off2[(t > 10.5) & (t < 11)] = True
    m2 = lane_metrics(t, lat, cmd, off2, 0.4, commands[:1])
    assert m2["commands"][0]["success"] is False and m2["off_track_events"] == 1
    both = overall_lane_metrics([m, m2])
    assert both["lane_changes"] == 3 and both["lane_changes_ok"] == 1


def test_a_change_succeeds_only_near_the_target_lane_centre():
    """Past the centre line is not enough: the car must come within lane_width / 4 of the new lane's
    centre (and hold it there); wrong-lane time still counts only the other side of the centre line."""
    dt = 0.1
    t = np.arange(0, 20, dt) + dt
    cmd = np.where(t < 5, 0.2, -0.2)
    lane_width = 0.4
    # the car drifts just past the centre line and stays 0.15 m from the right lane's centre
    lat = np.where(t < 5, 0.2, np.maximum(-0.05, 0.2 - (t - 5) * 0.5))
    off = np.zeros(t.size, bool)
    m = lane_metrics(t, lat, cmd, off, lane_width, [LaneCommand(5.0, -0.2, "Right_Lane")], time_limit=6.0, hold=1.0)
    assert m["commands"][0]["success"] is False and m["lane_change_success_rate"] == 0.0
    assert m["wrong_lane_s"] == 0.0  # right of the centre line: not the wrong lane
    # within a quarter lane (0.09 m from the centre): a success
    lat2 = np.where(t < 5, 0.2, np.maximum(-0.11, 0.2 - (t - 5) * 0.5))
    m2 = lane_metrics(t, lat2, cmd, off, lane_width, [LaneCommand(5.0, -0.2, "Right_Lane")], time_limit=6.0, hold=1.0)
    assert m2["commands"][0]["success"] is True
    # holding means staying near the centre: drifting back out before `hold` seconds restarts the hold
    lat3 = lat2.copy()
    lat3[(t > 5.8) & (t < 6.3)] = -0.05
    m3 = lane_metrics(t, lat3, cmd, off, lane_width, [LaneCommand(5.0, -0.2, "Right_Lane")], time_limit=6.0, hold=1.0)
    assert m3["commands"][0]["time_to_change_s"] > m2["commands"][0]["time_to_change_s"] + 0.4


def test_a_change_taken_back_while_waiting_does_not_shorten_the_next_wait(lanes_cfg):
    """Every road counts as tight here (curvature limit ~0), so a change waits the whole
    SIM_EXPERT_LANE_CHANGE_MAX_DELAY (3 s). Asked at 2 s and taken back at 2.5 s, the next request
    (at 6 s) waits its own 3 s, not what is left of the first one's."""
    cfg = lanes_cfg.replace(SIM_EXPERT_LANE_CHANGE_MAX_CURVATURE=1e-9)
    sim = SimCar.from_config(cfg, seeds=[2])
    expert = Expert.from_config(cfg, sim)
    started = None
    while sim.time < 12.0:
        t = sim.time
        state = 0 if 2.0 <= t < 2.5 or t >= 6.0 else 1
        sim.step(*expert.command(state))
        if t >= 6.0 and started is None and expert.changes_started:
            started = t
    assert expert.changes_started == 1
    assert started == pytest.approx(6.0 + cfg.SIM_EXPERT_LANE_CHANGE_MAX_DELAY, abs=2 * sim.dt)


def test_a_command_says_where_it_was_given_and_why_it_failed(lanes_cfg):
    """Issue 43: a failed change is understandable: each command carries the road's curvature ahead,
    the lane the car started in and whether the expert would have waited; a failure says why."""
    from parts.sim.lane_metrics import ChangeRule, LaneMetrics, describe_command

    track = SimCar.from_config(lanes_cfg, seeds=[3]).track
    rule = ChangeRule(0.9, 0.4)  # 1/m over 0.9 m ahead, as the expert's defaults (0.6 + 0.3 m)
    ahead = np.array([track.curvature_ahead(s, rule.distance) for s in track.s])
    straight, tight = float(track.s[int(np.argmin(ahead))]), float(track.s[int(np.argmax(ahead))])
    assert ahead.min() < rule.max_curvature < ahead.max()
    part = LaneMetrics(0.1, 0.4, time_limit=2.0, hold=0.5, rule=rule)
    part.on_track(track)
    right, left = track.lane_offset("right"), track.lane_offset("left")
    # 2 s in the right lane; at 2.1 s the left lane is commanded on the straight and the car stays
    # (too slow); at 6.1 s the right lane is commanded in the tight corner and the car leaves the road
    for k in range(1, 81):
        t = k * 0.1
        center, label = (right, "Right_Lane") if t < 2.05 or t > 6.05 else (left, "Left_Lane")
        s = straight if t < 6.05 else tight
        off = t > 6.45
        part.run(-right, off, center, track.pose_at(s, right)[:2], label)
    first, second = part.result()["commands"]
    assert (first["lane"], first["time_s"], first["start_lane"]) == ("Left_Lane", 2.1, "right")
    assert first["curvature_1pm"] == pytest.approx(ahead.min(), abs=1e-3) and first["expert_would_wait"] is False
    assert (first["success"], first["failure"], first["failed_at_s"]) == (False, "too_slow", 4.2)
    # the car never moved: it starts in the lane now commanded, but leaves the road before it has held it
    assert (second["lane"], second["time_s"], second["start_lane"]) == ("Right_Lane", 6.1, "right")
    assert second["curvature_1pm"] == pytest.approx(ahead.max(), abs=1e-3) and second["expert_would_wait"] is True
    assert (second["success"], second["failure"], second["failed_at_s"]) == (False, "off_road", 6.5)
    assert describe_command(second) == (f"to Right_Lane at 6.1 s from the right lane, curvature ahead "
                                        f"{ahead.max():.2f} 1/m (the expert would have waited); left the road at 6.5 s")
