"""The simulator as a Gymnasium environment: the checkers, seeded determinism, episode ends, reward files."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from parts.sim import gym_env
from parts.sim.gym_env import TrackEnv
from parts.sim.reward import RewardError, load_reward_function


@pytest.fixture
def env(cfg) -> TrackEnv:
    return TrackEnv(cfg, tracks=[1, 2], themes=["road", "indoor"])


def test_gymnasium_and_sb3_env_checkers_pass(cfg):
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    for kwargs in ({}, {"throttle": 0.3, "vector_obs": True}):
        e = TrackEnv(cfg, tracks=[1], **kwargs)
        check_env(e, skip_render_check=True)
        sb3_check_env(e, warn=False)


def test_registered_id_makes_the_env_and_a_vector_of_them(cfg):
    gym_env.register()
    e = gym.make("vehicle/Track-v0", config=cfg, tracks=[1], max_steps=7)
    obs, _ = e.reset(seed=0)
    assert obs.shape == (cfg.SIM_CAMERA_H, cfg.SIM_CAMERA_W, 3) and obs.dtype == np.uint8
    v = gym.make_vec("vehicle/Track-v0", num_envs=2, vectorization_mode="sync", config=cfg, tracks=[1, 2])
    obs, info = v.reset(seed=[3, 4])
    assert obs.shape == (2, cfg.SIM_CAMERA_H, cfg.SIM_CAMERA_W, 3)
    obs, reward, term, trunc, info = v.step(np.zeros((2, 2), np.float32))
    assert reward.shape == (2,) and "cte" in info
    v.close()


def _rollout(env: TrackEnv, seed: int, actions: np.ndarray) -> tuple[list[np.ndarray], list[float], dict]:
    obs, info = env.reset(seed=seed)
    frames, rewards = [obs], []
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        frames.append(obs)
        rewards.append(r)
        if term or trunc:
            break
    return frames, rewards, info


def test_same_seed_and_actions_give_the_same_observations_and_rewards(cfg):
    randomised = cfg.replace(SIM_RANDOMIZE=5)
    actions = np.random.default_rng(0).uniform([-0.3, 0.2], [0.3, 0.6], (30, 2)).astype(np.float32)
    a = _rollout(TrackEnv(randomised, tracks=[1, 2, 3], randomize_draws=3), 11, actions)
    b = _rollout(TrackEnv(randomised, tracks=[1, 2, 3], randomize_draws=3), 11, actions)
    assert all(np.array_equal(x, y) for x, y in zip(a[0], b[0], strict=True))
    assert a[1] == b[1] and sum(a[1]) > 0
    assert a[2]["track"] == b[2]["track"] and a[2]["draw"] == b[2]["draw"]


def test_reset_seeds_pick_tracks_themes_and_draws(env):
    picks = {(env.reset(seed=s)[1]["track"], env.theme) for s in range(12)}
    assert {t for t, _ in picks} == {1, 2} and {th for _, th in picks} == {"road", "indoor"}
    _, info = env.reset(options={"track": 2, "theme": "indoor"})
    assert (info["track"], env.theme) == (2, "indoor")


def test_leaving_the_road_terminates_and_the_time_limit_truncates(cfg):
    e = TrackEnv(cfg, tracks=[1], max_steps=400)
    e.reset(seed=0)
    for _ in range(400):  # full left lock at speed: off the road well before the limit
        _, r, term, trunc, info = e.step(np.array([-1.0, 0.6], np.float32))
        if term or trunc:
            break
    assert term and not trunc and info["off_track"] and r == 0.0
    e = TrackEnv(cfg, tracks=[1], max_steps=5)
    e.reset(seed=0)
    ends = [e.step(np.zeros(2, np.float32))[2:4] for _ in range(5)]
    assert ends[-1] == (False, True) and all(end == (False, False) for end in ends[:-1])


def test_a_lap_terminates_as_success(cfg):
    from parts.sim.expert import Expert

    e = TrackEnv(cfg, tracks=[1], laps=1)
    e.reset(seed=0)
    expert = Expert.from_config(cfg, e.sim)
    for _ in range(e.max_steps):
        angle, throttle = expert.run()[:2]
        _, _, term, trunc, info = e.step(np.array([angle, throttle], np.float32))
        if term or trunc:
            break
    assert term and not trunc and info["is_success"] and info["laps"] == 1 and len(info["lap_times"]) == 1


def test_params_hold_deepracers_documented_keys(cfg, tmp_path):
    seen = []
    e = TrackEnv(cfg, tracks=[1], reward=lambda p: seen.append(p) or 1.0)
    e.reset(seed=0)
    e.step(np.array([0.5, 0.5], np.float32))
    p = seen[0]
    for key in ("all_wheels_on_track", "x", "y", "closest_objects", "closest_waypoints", "distance_from_center",
                "is_crashed", "is_left_of_center", "is_offtrack", "is_reversed", "heading", "objects_distance",
                "objects_heading", "objects_left_of_center", "objects_location", "objects_speed", "progress",
                "speed", "steering_angle", "steps", "track_length", "track_width", "waypoints"):
        assert key in p, key
    assert p["steps"] == 1 and p["speed"] > 0 and 0 < p["progress"] < 1
    assert p["steering_angle"] < 0  # angle +0.5 steers right; DeepRacer's positive is left
    assert p["track_width"] == cfg.SIM_ROAD_WIDTH and p["all_wheels_on_track"] and not p["is_offtrack"]
    i, j = p["closest_waypoints"]
    assert j == (i + 1) % len(p["waypoints"])
    near = np.hypot(*(np.array(p["waypoints"][i]) - [p["x"], p["y"]]))
    assert near < 0.5


def _reward_file(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "reward.py"
    path.write_text("import math\n\n\ndef reward_function(params):\n" + body)
    return path


def test_a_reward_file_drives_the_reward(cfg, tmp_path):
    path = _reward_file(tmp_path, "    return 2.0 if params['all_wheels_on_track'] else 1e-3\n")
    e = TrackEnv(cfg, tracks=[1], reward=str(path))
    e.reset(seed=0)
    assert e.step(np.array([0.0, 0.3], np.float32))[1] == 2.0


def test_a_raising_reward_function_names_its_file_and_line(cfg, tmp_path):
    path = _reward_file(tmp_path, "    x = 1\n    return params['no_such_key']\n")
    e = TrackEnv(cfg, tracks=[1], reward=str(path))
    e.reset(seed=0)
    with pytest.raises(RewardError, match=rf"^{path}:6: reward_function raised KeyError: 'no_such_key'$"):
        e.step(np.zeros(2, np.float32))


@pytest.mark.parametrize("value", ["None", "'1.0'", "True", "float('nan')", "[1.0]"])
def test_a_reward_that_is_not_a_finite_number_is_refused_at_its_return_line(tmp_path, value):
    fn = load_reward_function(_reward_file(tmp_path, f"    x = 1\n    if x:\n        return {value}\n    return 0.0\n"))
    with pytest.raises(RewardError, match=r"reward\.py:7: reward_function returned .* must return a finite number"):
        fn({})


def test_each_reward_call_gets_its_own_params(cfg, tmp_path):
    """A function that appends to params["waypoints"] (or edits a point) changes nothing the next
    call sees."""
    path = _reward_file(tmp_path, "    n = len(params['waypoints'])\n    params['waypoints'].append([0, 0])\n"
                                  "    params['closest_waypoints'].append(0)\n    return float(n)\n")
    e = TrackEnv(cfg, tracks=[1], reward=str(path))
    e.reset(seed=0)
    counts = {e.step(np.array([0.0, 0.3], np.float32))[1] for _ in range(3)}
    assert len(counts) == 1 and counts.pop() > 10
    seen = []
    e = TrackEnv(cfg, tracks=[1], reward=lambda p: seen.append(p["waypoints"]) or 1.0)
    e.reset(seed=0)
    e.step(np.zeros(2, np.float32))
    e.step(np.zeros(2, np.float32))
    assert seen[0] is not seen[1] and seen[0] == seen[1]
    with pytest.raises(TypeError):  # a point cannot be edited in place
        seen[0][0][0] = 99.0


def test_a_reward_function_that_never_returns_is_stopped_in_one_line(cfg, tmp_path):
    path = _reward_file(tmp_path, "    while True:\n        pass\n")
    e = TrackEnv(cfg.replace(RL_REWARD_TIME_LIMIT_S=0.2), tracks=[1], reward=str(path))
    e.reset(seed=0)
    with pytest.raises(RewardError, match=rf"^{path}:4: reward_function did not return within 0.2 s "
                                          r"\(RL_REWARD_TIME_LIMIT_S\)"):
        e.step(np.zeros(2, np.float32))
    e.reset(seed=0)  # the env is still usable, and the limit holds again (the timer was rearmed)
    with pytest.raises(RewardError, match="did not return within 0.2 s"):
        e.step(np.zeros(2, np.float32))


def test_a_stop_signal_in_a_reward_function_is_not_blamed_on_it(tmp_path):
    from vehicle.errors import VehicleStopped

    fn = load_reward_function(_reward_file(tmp_path, "    raise KeyboardInterrupt\n"))
    with pytest.raises(KeyboardInterrupt):
        fn({})
    path = tmp_path / "stopped.py"
    path.write_text("from vehicle.errors import VehicleStopped\n\n\ndef reward_function(params):\n"
                    "    raise VehicleStopped(15, 'SIGTERM')\n")
    with pytest.raises(VehicleStopped):
        load_reward_function(path)({})


def test_bad_reset_options_are_refused_in_one_line_naming_the_option(cfg):
    e = TrackEnv(cfg, tracks=[1])
    with pytest.raises(ValueError, match=r"^options\['track'\] = 'nope': give a track seed, an int from 0"):
        e.reset(options={"track": "nope"})
    with pytest.raises(ValueError, match=r"^options\['draw'\] = -1"):
        e.reset(options={"draw": -1})
    with pytest.raises(ValueError, match=r"^options\['theme'\] = 'lava': give one of .*road"):
        e.reset(options={"theme": "lava"})
    with pytest.raises(ValueError, match=r"^reset\(options=\.\.\.\): unknown option 'trak'; the options are "
                                         r"track, theme, draw"):
        e.reset(options={"trak": 3})
    assert e.reset(options={"track": 7, "theme": "indoor"})[1]["track"] == 7


def test_the_default_env_varies_with_the_seed(cfg):
    """RL users expect reset(seed=0) and reset(seed=1) to give different episodes: with the
    defaults the env draws from several training tracks."""
    e = gym.make(gym_env.ENV_ID, config=cfg)
    tracks = {e.reset(seed=s)[1]["track"] for s in range(6)}
    assert len(tracks) > 1


def test_a_relative_config_path_is_taken_from_the_current_folder(tmp_path, monkeypatch):
    car = tmp_path / "mycar"
    car.mkdir()
    (car / "myconfig.py").write_text("SIM_ROAD_WIDTH = 1.1\n")
    monkeypatch.chdir(tmp_path)
    e = gym.make(gym_env.ENV_ID, config="mycar/myconfig.py")
    assert e.unwrapped.cfg.SIM_ROAD_WIDTH == 1.1


def test_reward_files_that_cannot_load_say_why(tmp_path):
    with pytest.raises(RewardError, match="no such reward file"):
        load_reward_function(tmp_path / "missing.py")
    bad = tmp_path / "syntax.py"
    bad.write_text("def reward_function(params)\n    return 1\n")
    with pytest.raises(RewardError, match=rf"^{bad}:1: syntax error"):
        load_reward_function(bad)
    none = tmp_path / "none.py"
    none.write_text("def reward(params):\n    return 1.0\n")
    with pytest.raises(RewardError, match="defines no reward_function"):
        load_reward_function(none)


def test_a_reward_function_travels_to_worker_processes(tmp_path):
    import pickle

    fn = load_reward_function(_reward_file(tmp_path, "    return params['speed'] * 2\n"))
    assert pickle.loads(pickle.dumps(fn))({"speed": 1.5}) == 3.0
