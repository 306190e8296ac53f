"""RL with throttle control: the throttle range's action map and its exact fold into the pilot
file, the speed reward, the linear model's throttle limits, and fine-tuning a behaviour-cloned
pilot (value-function warm-up keeps the actor as cloned; the result loads and drives
deterministically in the Vehicle loop)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from vehicle.config import Config


@pytest.fixture
def small() -> Config:
    """A small camera and a coarse texture: training steps are cheap."""
    return Config.defaults(SIM_TEXTURE_RES=0.02, SIM_REALTIME=False, SIM_CAMERA_W=80, SIM_CAMERA_H=64,
                           SIM_EVAL_MAX_TIME=4.0)


def _prep_meta(cfg: Config) -> tuple[object, dict]:
    from parts.pilots.preprocess import preprocess_from_config

    prep = preprocess_from_config(cfg, "linear", image_shape=(cfg.SIM_CAMERA_H, cfg.SIM_CAMERA_W, 3))
    return prep, {"preprocess": {**prep.to_dict(), "image_shape": [cfg.SIM_CAMERA_H, cfg.SIM_CAMERA_W, 3]}}


def _bc_pilot(cfg: Config, path, throttle: float = 0.45):
    """A stand-in for a behaviour-cloned linear pilot: random trunk, straight ahead at ``throttle``."""
    from parts.pilots.modelfile import save_model
    from parts.pilots.models import create_model

    torch.manual_seed(7)
    model = create_model("linear", (3, cfg.SIM_CAMERA_H, cfg.SIM_CAMERA_W), dropout=0.0)
    with torch.no_grad():
        model.head[-1].weight.mul_(0.01)
        model.head[-1].bias.copy_(torch.tensor([0.0, throttle]))
    _, meta = _prep_meta(cfg)
    return save_model(path, model, {**meta, "type": "linear"}), model


def test_the_throttle_action_spans_the_range(small):
    from parts.sim.gym_env import TrackEnv, check_throttle_range, throttle_from_action

    assert throttle_from_action(-1.0, (0.2, 0.8)) == pytest.approx(0.2)
    assert throttle_from_action(0.0, (0.2, 0.8)) == pytest.approx(0.5)
    assert throttle_from_action(1.0, (0.2, 0.8)) == pytest.approx(0.8)
    assert throttle_from_action(0.3, None) == pytest.approx(0.3)
    for bad in ((0.8, 0.2), (0.0, 1.5), (0.5,), "ab"):
        with pytest.raises(ValueError, match="throttle_range"):
            check_throttle_range(bad)
    with pytest.raises(ValueError, match="not both"):
        TrackEnv(small, tracks=[1], throttle=0.3, throttle_range=(0.2, 0.8))

    env = TrackEnv(small.replace(AI_THROTTLE_MULT=0.5), tracks=[1], throttle_range=(0.2, 0.8))
    env.reset(seed=0)
    sent = []
    step = env.sim.step
    env.sim.step = lambda angle, throttle: sent.append((angle, throttle)) or step(angle, throttle)
    for a in ([0.1, -1.0], [0.0, 0.0], [0.0, 1.0], [0.0, 3.0], [0.0, -7.0]):
        env.step(np.array(a, np.float32))
    # the range, then AI_THROTTLE_MULT as DriveMode applies it; actions beyond [-1, 1] clip to its ends
    assert [t for _, t in sent] == pytest.approx([0.1, 0.25, 0.4, 0.4, 0.1])
    assert env.last_action == pytest.approx((0.0, 0.2))


def test_linear_throttle_limits_clamp_only_the_throttle():
    from parts.pilots.models import create_model

    out = torch.tensor([[0.9, 0.95], [-2.0, -0.5], [0.1, 0.5]])
    plain = create_model("linear", (3, 64, 80))
    assert plain.options["throttle_limits"] is None and torch.equal(plain.controls(out), out)
    capped = create_model("linear", (3, 64, 80), throttle_limits=[0.2, 0.8])
    assert torch.allclose(capped.controls(out), torch.tensor([[0.9, 0.8], [-2.0, 0.2], [0.1, 0.5]]))
    for bad in ([0.8, 0.2], [0.0, 2.0], 0.5):
        with pytest.raises(ValueError, match="throttle_limits"):
            create_model("linear", (3, 64, 80), throttle_limits=bad)


def test_the_speed_reward_pays_for_speed_along_the_centre():
    from parts.sim.reward import RewardError, default_reward, load_reward_function, speed_reward

    p = {"is_offtrack": False, "track_width": 1.0, "distance_from_center": 0.0, "speed": 2.0,
         "heading_error": 0.0, "dt": 0.05}
    assert default_reward(p) == pytest.approx(0.1)
    assert speed_reward(p) == pytest.approx(0.2)  # twice as fast: twice per metre
    assert speed_reward({**p, "speed": 1.0}) == pytest.approx(0.05)
    assert speed_reward({**p, "distance_from_center": 0.25}) == pytest.approx(0.2 * 0.75)
    assert speed_reward({**p, "heading_error": 60.0}) == pytest.approx(0.05)  # 1 m/s along the track, 1 m/s
    assert speed_reward({**p, "speed": -1.0}) == 0.0
    assert speed_reward({**p, "is_offtrack": True}) == 0.0
    assert load_reward_function("speed") is speed_reward and load_reward_function("default") is default_reward
    with pytest.raises(RewardError, match="built-in rewards default, speed"):
        load_reward_function("fast")


def _ppo(cfg: Config, throttle_range=(0.2, 0.8)):
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    from parts.sim.gym_env import TrackEnv
    from training.rl import policy_kwargs

    prep, meta = _prep_meta(cfg)
    venv = DummyVecEnv([lambda: TrackEnv(cfg, tracks=[1], throttle_range=throttle_range, frame=prep.frame)])
    model = PPO("CnnPolicy", venv, n_steps=64, batch_size=32, seed=0, device="cpu",
                policy_kwargs=policy_kwargs("ppo", "linear", {"dropout": 0.0}, prep.normalize,
                                            log_std_init=-1.6, share_trunk=False))
    return model, venv, meta


def test_the_range_folds_into_the_pilot_file_exactly(small, tmp_path):
    """From a cloned pilot into the policy and back gives the pilot; the exported file drives the
    throttle the environment applies for the policy's deterministic action, clamped as it is."""
    from parts.pilots import load_pilot
    from parts.sim.gym_env import TrackEnv, throttle_from_action
    from training.rl import export_pilot, load_pilot_weights, policy_model

    rng = (0.2, 0.8)
    model, venv, meta = _ppo(small, rng)
    _, bc = _bc_pilot(small, tmp_path / "bc.pt")
    load_pilot_weights(model.policy, bc, rng)
    assert model.policy.action_net.bias[1].item() == pytest.approx((0.45 - 0.5) / 0.3)
    back = policy_model(model.policy, rng).state_dict()
    assert all(torch.allclose(back[k], v, atol=1e-6) for k, v in bc.state_dict().items())
    assert model.policy.log_std.exp().tolist() == pytest.approx([math.exp(-1.6)] * 2)

    prep, _ = _prep_meta(small)
    env = TrackEnv(small, tracks=[1], throttle_range=rng, frame=prep.frame)
    for bias in (0.45, 3.0):  # within the range; far beyond it (the action clipped, the file clamped)
        with torch.no_grad():
            model.policy.action_net.bias[1] = bias
        pilot = load_pilot(export_pilot(model.policy, tmp_path / "rl.pt", meta, rng), backend="torch")
        obs, _ = env.reset(seed=0)
        for _ in range(3):
            action, _ = model.predict(obs, deterministic=True)
            angle, thr = pilot.run(env._image)
            assert angle == pytest.approx(float(action[0]), abs=1e-5)
            assert thr == pytest.approx(throttle_from_action(float(np.clip(action[1], -1, 1)), rng), abs=1e-5)
            obs = env.step(action)[0]
    assert thr == pytest.approx(0.8)
    from training.export import export_model  # the ONNX export clamps the same way

    onnx = load_pilot(export_model(tmp_path / "rl.pt", "onnx"), backend="onnx")
    assert onnx.run(env._image)[1] == pytest.approx(0.8, abs=1e-5)
    venv.close()


@pytest.mark.slow
def test_fine_tuning_a_cloned_pilot_warms_the_critic_first_and_drives_deterministically(small, tmp_path):
    """BC pilot -> rl train --init with a throttle range and a value-function warm-up as long as
    the run: the actor is not moved (the file drives as the cloned pilot), the critic learned, and
    the kept pilot loads and drives the same trajectory twice in the Vehicle loop."""
    from parts.pilots.modelfile import load_model
    from vehicle.app.evaluate import evaluate
    from vehicle.app.rl_train import RLSettings, sidecars, train_rl

    bc_path, bc = _bc_pilot(small, tmp_path / "bc.pt")
    out = tmp_path / "models" / "ft.pt"
    s = RLSettings(timesteps=128, envs=1, tracks=[1], eval_tracks=[101], eval_every=0, init=str(bc_path),
                   throttle_range=(0.2, 0.8), vf_warmup=128, max_steps=40, n_steps=64, batch_size=32,
                   n_epochs=2, learning_rate=1e-3, target_kl=0.02, clip_range=0.1, reward="speed")
    curve = train_rl(small, out, s)
    assert curve["best"] is not None and out.is_file()
    tuned, meta = load_model(out)
    assert meta["model"]["options"]["throttle_limits"] == [0.2, 0.8]
    assert meta["training"]["throttle_range"] == [0.2, 0.8] and meta["training"]["reward"] == "speed"
    got = tuned.state_dict()
    assert all(torch.allclose(got[k], v, atol=1e-6) for k, v in bc.state_dict().items())  # actor frozen

    from stable_baselines3 import PPO

    state = PPO.load(sidecars(out)["state"], device="cpu")
    critic = state.policy.vf_features_extractor.features[0].weight
    assert not torch.allclose(critic, bc.features[0].weight)  # the critic's own trunk learned

    a = evaluate(str(out), [101], 1, cfg=small)
    b = evaluate(str(out), [101], 1, cfg=small)
    assert a["tracks"][0]["trajectory"] == b["tracks"][0]["trajectory"]
    assert a["tracks"][0]["distance_m"] > 0.5


@pytest.mark.slow
def test_a_short_run_with_the_throttle_learns_to_speed_up(small, tmp_path):
    """PPO from scratch with throttle control over (0, 1), rewarded by the speed reward on short
    episodes: the mean episode reward of the last rollouts beats the first."""
    from vehicle.app.rl_train import RLSettings, train_rl

    s = RLSettings(timesteps=2048, envs=1, tracks=[1], eval_tracks=[101], eval_every=0, reward="speed",
                   throttle_range=(0.0, 1.0), max_steps=32, n_steps=256, batch_size=64, n_epochs=4,
                   learning_rate=1e-3, seed=3)
    curve = train_rl(small, tmp_path / "rl.pt", s)
    rewards = [r["mean_reward"] for r in curve["rollouts"] if r["mean_reward"] is not None]
    assert rewards[-1] > 1.2 * rewards[0], rewards  # measured: 1.53 -> 1.98 (seed 3)


def test_rl_train_refuses_a_throttle_range_it_cannot_honour(small, tmp_path):
    from vehicle.app.rl_train import RLSettings, train_rl
    from vehicle.errors import UserError

    with pytest.raises(UserError, match="not both"):
        train_rl(small, tmp_path / "rl.pt", RLSettings(throttle=0.3, throttle_range=(0.2, 0.8)))
    with pytest.raises(UserError, match="for PPO"):
        train_rl(small, tmp_path / "rl.pt", RLSettings(algo="sac", throttle_range=(0.2, 0.8)))
    assert not (tmp_path / "rl.pt").exists()


def test_cli_refuses_a_bad_throttle_range():
    import argparse

    from vehicle.app.commands.rl import _range

    assert _range("0.2,0.8") == (0.2, 0.8)
    for bad in ("0.8,0.2", "0.2", "a,b", "0,2"):
        with pytest.raises(argparse.ArgumentTypeError, match="LOW,HIGH"):
            _range(bad)
