"""RL pilots: the policy is the pilot model, exports exactly, drives deterministically in the Vehicle
loop, starts from a behaviour-cloned pilot, and a short training run improves the reward."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from vehicle.config import Config


@pytest.fixture
def small() -> Config:
    """A small camera (64x80: the linear model's smallest comfortable input) and a coarse texture:
    training steps are cheap."""
    return Config.defaults(SIM_TEXTURE_RES=0.02, SIM_REALTIME=False, SIM_CAMERA_W=80, SIM_CAMERA_H=64,
                           SIM_EVAL_MAX_TIME=4.0)


def _ppo(cfg: Config, throttle: float | None = None, seed: int = 0):
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    from parts.pilots.preprocess import preprocess_from_config
    from parts.sim.gym_env import TrackEnv
    from training.rl import model_options, policy_kwargs, policy_model_type

    mtype = policy_model_type("ppo", throttle is not None)
    prep = preprocess_from_config(cfg, mtype, image_shape=(cfg.SIM_CAMERA_H, cfg.SIM_CAMERA_W, 3))
    venv = DummyVecEnv([lambda: TrackEnv(cfg, tracks=[1], throttle=throttle, frame=prep.frame)])
    model = PPO("CnnPolicy", venv, n_steps=64, batch_size=32, seed=seed, device="cpu",
                policy_kwargs=policy_kwargs("ppo", mtype, model_options(mtype, throttle), prep.normalize))
    meta = {"preprocess": {**prep.to_dict(), "image_shape": [cfg.SIM_CAMERA_H, cfg.SIM_CAMERA_W, 3]}}
    return model, venv, meta


@pytest.mark.parametrize("throttle", [None, 0.4])
def test_the_exported_pilot_computes_the_policys_deterministic_action(small, tmp_path, throttle):
    from parts.pilots import load_pilot
    from parts.pilots.preprocess import Preprocess
    from parts.sim.gym_env import TrackEnv
    from training.rl import export_pilot

    model, venv, meta = _ppo(small, throttle)
    with torch.no_grad():  # a policy whose outputs are not all near zero
        model.policy.action_net.bias.copy_(torch.tensor([0.3, 0.5][:1 if throttle else 2]))
    path = export_pilot(model.policy, tmp_path / "rl.pt", meta)
    loaded = torch.load(path, weights_only=True)  # weights and plain metadata only
    assert loaded["format"] == "vehicle-pilot"
    assert loaded["meta"]["model"]["type"] == ("inferred" if throttle else "linear")
    pilot = load_pilot(path, backend="torch")
    env = TrackEnv(small, tracks=[1], throttle=throttle, frame=Preprocess.from_dict(meta["preprocess"]).frame)
    obs, _ = env.reset(seed=0)
    for _ in range(5):
        action, _ = model.predict(obs, deterministic=True)
        angle, thr = pilot.run(env._image)
        assert angle == pytest.approx(float(action[0]), abs=1e-5)
        assert thr == pytest.approx(throttle if throttle else float(action[1]), abs=1e-5)
        obs = env.step(action)[0]
    venv.close()


def test_the_exported_pilot_drives_deterministically_in_the_vehicle_loop_and_exports(small, tmp_path):
    from training.export import export_model
    from training.rl import export_pilot
    from vehicle.app.evaluate import evaluate

    model, venv, meta = _ppo(small)
    with torch.no_grad():
        model.policy.action_net.bias.copy_(torch.tensor([0.0, 0.4]))
    path = export_pilot(model.policy, tmp_path / "rl.pt", meta)
    a = evaluate(str(path), [101], 1, cfg=small)
    b = evaluate(str(path), [101], 1, cfg=small)
    assert a["tracks"][0]["trajectory"] == b["tracks"][0]["trajectory"]
    assert a["tracks"][0]["distance_m"] > 0.5  # it drove
    assert export_model(path, "onnx").is_file()
    assert export_model(path, "onnx-int8", int8="dynamic").is_file()
    venv.close()


def test_a_policy_starts_from_a_behaviour_cloned_pilot(small, tmp_path):
    from parts.pilots.models import create_model
    from training.rl import load_pilot_weights, policy_model

    model, venv, _ = _ppo(small)
    torch.manual_seed(1)
    bc = create_model("linear", (3, 64, 80))
    load_pilot_weights(model.policy, bc)
    got = policy_model(model.policy).state_dict()
    assert all(torch.equal(got[k], v) for k, v in bc.state_dict().items())
    with pytest.raises(ValueError, match="'inferred' model"):
        load_pilot_weights(model.policy, create_model("inferred", (3, 64, 80)))
    venv.close()


@pytest.mark.slow
def test_a_short_training_run_improves_the_mean_reward(small, tmp_path):
    """PPO on one environment for 3072 steps, rewarded for throttle: the episode reward of the
    last rollouts beats the first ones by a wide margin, and the best pilot is kept and loads."""
    from parts.pilots import load_pilot
    from vehicle.app.rl_train import RLSettings, sidecars, train_rl

    reward = tmp_path / "reward.py"
    reward.write_text("def reward_function(params):\n    return params['throttle'] if params['all_wheels_on_track'] "
                      "else -1.0\n")
    out = tmp_path / "models" / "rl.pt"
    # evaluated every 1024 steps: at this test's learning rate an update can undo what the run
    # learnt (on an AMD EPYC the very last one turned the throttle from +0.9 to -1.3), and the
    # pilot kept is the best evaluated, not the last
    s = RLSettings(timesteps=3072, envs=1, tracks=[1], eval_tracks=[101], eval_every=1024, reward=str(reward),
                   max_steps=32, n_steps=256, batch_size=64, n_epochs=4, learning_rate=1e-3, seed=3)
    curve = train_rl(small, out, s)
    rewards = [r["mean_reward"] for r in curve["rollouts"] if r["mean_reward"] is not None]
    first, last = rewards[0], rewards[-1]
    assert last > first + 3.0, rewards  # 32 steps: +0.1 throttle per step on average at least
    assert curve["best"] is not None and out.is_file()
    files = sidecars(out)
    assert files["state"].is_file() and files["plot"].is_file()
    assert json.loads(files["curve"].read_text())["rollouts"] == curve["rollouts"]
    from parts.sim.gym_env import TrackEnv

    frame = TrackEnv(small, tracks=[1]).reset(seed=0)[0]  # what the camera shows at the start line
    assert load_pilot(out).run(frame)[1] > 0.0  # (a black frame is no road: its answer says nothing)


def test_cli_refuses_a_bad_reward_file_in_one_line(tmp_path, capsys):
    from vehicle.app.cli import main

    bad = tmp_path / "reward.py"
    bad.write_text("def reward_function(params)\n")
    assert main(["rl", "train", "--car", str(tmp_path), "--reward", str(bad), "--steps", "10"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {bad}:1: syntax error")


def test_sidecars_sit_beside_the_pilot():
    from vehicle.app.rl_train import sidecars

    f = sidecars(Path("models/rl.pt"))
    assert f["state"] == Path("models/rl.rl.zip") and f["curve"] == Path("models/rl.rl.json")


@pytest.mark.slow
def test_ctrl_c_keeps_the_best_and_resume_goes_on(small, tmp_path):
    """KeyboardInterrupt in the middle of training: the state and the best pilot are kept and the
    interrupt propagates (the CLI exits 130); --resume continues from the saved step count."""
    from vehicle.app.rl_train import RLSettings, sidecars, train_rl

    out = tmp_path / "rl.pt"
    s = RLSettings(timesteps=1024, envs=1, tracks=[1], eval_tracks=[101], eval_every=128, max_steps=40,
                   n_steps=128, batch_size=64, n_epochs=1, seed=1)
    seen = []

    def interrupt(event):
        seen.append(event)
        if event["event"] == "evaluation" and event["timesteps"] >= 256:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        train_rl(small, out, s, on_event=interrupt)
    files = sidecars(out)
    assert out.is_file() and files["state"].is_file() and not files["eval"].exists()
    stopped = json.loads(files["curve"].read_text())
    assert stopped["evaluations"][-1]["timesteps"] == 256 and stopped["best"] is not None
    s.resume, s.timesteps = True, 512
    curve = train_rl(small, out, s)
    # one rollout ended before the interrupt (during the second); resumed at 256 steps, two more
    assert [r["timesteps"] for r in curve["rollouts"]] == [128, 384, 512]
    assert [e["timesteps"] for e in curve["evaluations"]] == [128, 256, 384, 512]


@pytest.mark.slow
def test_sigterm_stops_training_like_ctrl_c(small, tmp_path):
    """SIGTERM (a service manager, `kill`) in the middle of training: the state and the best pilot
    are kept and VehicleStopped propagates (the CLI exits 128 + 15)."""
    import os
    import signal

    from vehicle.app.rl_train import RLSettings, sidecars, train_rl
    from vehicle.errors import VehicleStopped

    out = tmp_path / "rl.pt"
    s = RLSettings(timesteps=4096, envs=1, tracks=[1], eval_tracks=[101], eval_every=64, eval_laps=1,
                   max_steps=20, n_steps=64, batch_size=64, n_epochs=1, seed=1)

    def terminate(event):
        if event["event"] == "evaluation":
            os.kill(os.getpid(), signal.SIGTERM)

    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(VehicleStopped) as stopped:
        train_rl(small.replace(SIM_EVAL_MAX_TIME=1.0), out, s, on_event=terminate)
    assert stopped.value.signum == signal.SIGTERM
    assert out.is_file() and sidecars(out)["state"].is_file()
    assert signal.getsignal(signal.SIGTERM) is before  # the handler is given back


@pytest.mark.parametrize("envs", [1, 2])
def test_a_failing_reward_stops_training_in_one_line_for_every_env_count_and_leaves_nothing(tmp_path, capsys, envs):
    from vehicle.app.cli import main

    (tmp_path / "myconfig.py").write_text("SIM_TEXTURE_RES = 0.02\nSIM_CAMERA_W = 80\nSIM_CAMERA_H = 64\n")
    reward = tmp_path / "reward.py"
    reward.write_text("def reward_function(params):\n    if params['steps'] > 3:\n        return float('nan')\n"
                      "    return 1.0\n")
    code = main(["rl", "train", "--car", str(tmp_path), "--reward", str(reward), "--steps", "256", "--envs",
                 str(envs), "--n-steps", "64", "--batch-size", "32", "--no-progress"])
    err = [line for line in capsys.readouterr().err.splitlines() if not line[:2].isdigit()]  # not log lines
    assert code == 2
    assert err == [f"error: {reward}:3: reward_function returned nan (float); it must return a finite number, "
                   "e.g. float(reward)"]
    assert sorted(p.name for p in (tmp_path / "models").iterdir() if p.name != "models.db") == []


def test_sac_without_the_progress_bar_logs_a_line_per_row_of_steps_not_per_step(small, tmp_path, caplog):
    from vehicle.app.rl_train import ROW_STEPS, RLSettings, train_rl

    # no gradient step (learning_starts beyond the run): only the rollouts' bookkeeping is tested
    s = RLSettings(algo="sac", timesteps=ROW_STEPS + 10, envs=1, tracks=[1], eval_tracks=[101], eval_every=0,
                   max_steps=30, batch_size=16, seed=1, extra={"learning_starts": 10_000, "buffer_size": 400})
    with caplog.at_level("INFO", logger="vehicle.app.rl_train"):
        curve = train_rl(small.replace(SIM_EVAL_MAX_TIME=1.0), tmp_path / "sac.pt", s)
    lines = [r for r in caplog.records if "steps/s" in r.getMessage()]
    assert [r["timesteps"] for r in curve["rollouts"]] == [1, ROW_STEPS + 1]
    assert len(lines) == 2


def test_a_training_run_leaves_no_folder_in_the_temporary_directory(small, tmp_path, monkeypatch):
    # stable-baselines3 configures a logger for every learn() without one of its own, and that
    # made an empty /tmp/SB3-<date-time> folder per run
    import tempfile

    from vehicle.app.rl_train import RLSettings, train_rl

    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    s = RLSettings(algo="sac", timesteps=20, envs=1, tracks=[1], eval_tracks=[101], eval_every=0,
                   max_steps=30, batch_size=16, seed=1, extra={"learning_starts": 10_000, "buffer_size": 400})
    train_rl(small.replace(SIM_EVAL_MAX_TIME=1.0), tmp_path / "sac.pt", s)
    assert [p.name for p in tmp.iterdir() if p.name.startswith("SB3-")] == []  # torch may cache there
