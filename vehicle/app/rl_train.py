"""``vehicle rl train``: reinforcement learning of a pilot in the built-in simulator (stable-baselines3).

PPO (default) or SAC on ``envs`` copies of :class:`parts.sim.gym_env.TrackEnv` (one process per
core), the actor being a pilot model (:mod:`training.rl`). Every ``eval_every`` steps the actor
is exported as a pilot model file and driven by :func:`vehicle.app.evaluate.evaluate` on held-out
tracks, closed loop in the Vehicle loop; the best (highest autonomy times the share of the laps
driven, then mean speed) is kept at ``out``, an ordinary model file, registered like a trained pilot. Beside it:
``<out>.rl.zip`` (SB3 state: ``resume``), ``<out>.rl.json`` (the learning curve) and
``<out>.rl.png`` (its plot). Ctrl-C (or SIGTERM / SIGHUP) stops between steps: the state is saved,
the best pilot kept, and the interrupt propagates (the CLI exits 130, or 128 + the signal).
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import signal
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from vehicle.errors import UserError, VehicleStopped
from vehicle.vehicle import STOP_SIGNALS, handling

logger = logging.getLogger(__name__)


#: with an off-policy algorithm (SAC), steps between two rows of the learning curve (and log lines)
ROW_STEPS = 256


@dataclass
class RLSettings:
    """What ``vehicle rl train`` runs (its options)."""

    algo: str = "ppo"
    timesteps: int = 100_000
    envs: int = 0  # 0: one per core
    tracks: list[int] | None = None  # default SIM_TRACK_SEEDS
    eval_tracks: list[int] | None = None  # default SIM_EVAL_TRACK_SEEDS
    eval_every: int = 20_000  # steps; 0: only at the end
    eval_laps: int = 1
    reward: str | None = None  # reward file; None: parts.sim.reward.default_reward
    throttle: float | None = None  # steering only at this throttle
    throttle_range: tuple[float, float] | None = None  # the throttle action's [-1, 1] spans (low, high)
    laps: int = 1  # laps that end an episode
    max_steps: int | None = None
    randomize_draws: int = 1
    init: str | None = None  # behaviour-cloned pilot to start from
    resume: bool = False
    seed: int = 0
    n_steps: int = 256  # PPO: steps per env per update
    batch_size: int = 64
    n_epochs: int = 4
    learning_rate: float = 3e-4
    gamma: float = 0.99
    clip_range: float = 0.2  # PPO: how far one update may move the policy's probability ratio
    target_kl: float | None = None  # PPO: stop an update's epochs once the KL to the old policy passes this
    log_std_init: float | None = None  # PPO: log of the starting exploration std (None: -0.5, with init -1.6)
    vf_warmup: int = 0  # PPO: steps during which only the critic learns (the actor frozen)
    comment: str = ""
    extra: dict[str, Any] = field(default_factory=dict)  # more SB3 algorithm arguments


def sidecars(out: Path) -> dict[str, Path]:
    """Files written beside the pilot ``out``."""
    return {k: out.with_name(out.stem + suffix) for k, suffix in
            (("state", ".rl.zip"), ("curve", ".rl.json"), ("plot", ".rl.png"), ("eval", ".rl-eval.pt"))}


def _make_env(config: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
    import cv2
    from stable_baselines3.common.monitor import Monitor

    from parts.sim.gym_env import TrackEnv
    from vehicle.config import Config

    cv2.setNumThreads(1)  # one process per core already
    return Monitor(_ReportErrors(TrackEnv(Config(*config), **kwargs)))


def _ReportErrors(env: Any) -> Any:  # noqa: N802 - builds a gymnasium wrapper class lazily
    """``env`` wrapped so that a user's error in a step (a reward function that raises, returns NaN or
    runs out of time: a VehicleError) ends the episode with the message in ``info["error"]``
    instead of killing a worker process; :meth:`_Trainer.on_step` raises it in the trainer. So the
    message is the same one line for one environment or several."""
    import gymnasium as gym

    from vehicle.errors import VehicleError

    class ReportErrors(gym.Wrapper):
        def __init__(self, inner: Any) -> None:
            super().__init__(inner)
            self.last_obs: Any = None

        def reset(self, **kwargs: Any) -> Any:
            self.last_obs, info = self.env.reset(**kwargs)
            return self.last_obs, info

        def step(self, action: Any) -> Any:
            try:
                self.last_obs, *rest = self.env.step(action)
            except VehicleError as exc:
                return self.last_obs, 0.0, True, False, {"error": str(exc)}
            return (self.last_obs, *rest)

    return ReportErrors(env)


@contextlib.contextmanager
def _sigint_ignored() -> Iterator[None]:
    """Start worker processes ignoring Ctrl-C: only the trainer stops, and closes them."""
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def make_vec_env(cfg: Any, env_kwargs: dict[str, Any], n_envs: int, seed: int) -> Any:
    """``n_envs`` environments: in this process for one, else one worker process each."""
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    from vehicle.app.evaluate import _sendable_config  # a Config travels as its values

    fns = [partial(_make_env, _sendable_config(cfg), env_kwargs) for _ in range(n_envs)]
    if n_envs == 1:
        venv = DummyVecEnv(fns)
    else:
        with _sigint_ignored():
            venv = SubprocVecEnv(fns, start_method="forkserver")
    venv.seed(seed)
    return venv


def _algorithm(name: str) -> Any:
    from stable_baselines3 import PPO, SAC

    return {"ppo": PPO, "sac": SAC}[name]


def train_rl(cfg: Any, out: str | Path, s: RLSettings, *, progress: bool = False,
             on_event: Callable[[dict[str, Any]], None] | None = None) -> dict[str, Any]:
    """Train (or resume) and keep the best pilot at ``out``; returns the learning curve and the best
    evaluation. Raises KeyboardInterrupt (Ctrl-C) or VehicleStopped (SIGTERM, SIGHUP) after saving
    when interrupted."""
    from parts.sim.reward import load_reward_function
    from training.rl import policy_model_type

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    files = sidecars(out)
    algo = s.algo.lower()
    try:
        mtype = policy_model_type(algo, s.throttle is not None)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    load_reward_function(s.reward)  # a bad file fails now, in one line, not in a worker
    if s.throttle_range is not None and algo != "ppo":
        raise UserError("--throttle-range is for PPO (SAC's actions are already bounded by tanh)")
    if cfg.CAMERA_UNDISTORT and cfg.SIM_CAMERA_DISTORTION:
        raise UserError("rl train renders frames without undistortion: set CAMERA_UNDISTORT = False or "
                        "SIM_CAMERA_DISTORTION = None")
    image_shape = (cfg.SIM_CAMERA_H, cfg.SIM_CAMERA_W, 3)
    init_model, options, prep = _starting_point(cfg, s, algo, mtype, image_shape)
    tracks = list(s.tracks or cfg.SIM_TRACK_SEEDS)
    eval_tracks = list(s.eval_tracks or cfg.SIM_EVAL_TRACK_SEEDS)
    if set(tracks) & set(eval_tracks):
        logger.warning("evaluation tracks %s are also training tracks: the evaluation is not held out",
                       sorted(set(tracks) & set(eval_tracks)))
    if s.throttle_range is not None and s.throttle is not None:
        raise UserError("give --throttle (steering only) or --throttle-range (the policy's throttle), not both")
    env_kwargs = {"tracks": tracks, "throttle": s.throttle, "throttle_range": s.throttle_range,
                  "laps": s.laps, "max_steps": s.max_steps,
                  "reward": s.reward, "frame": prep.frame, "randomize_draws": s.randomize_draws}
    n_envs = s.envs or os.cpu_count() or 1
    meta = _pilot_meta(cfg, s, prep, image_shape, tracks, eval_tracks, n_envs)
    curve: dict[str, Any] = {"rollouts": [], "evaluations": [], "best": None}
    if s.resume:
        if not files["state"].is_file():
            raise UserError(f"--resume: no training state {files['state']}; start without --resume")
        if files["curve"].is_file():
            curve = json.loads(files["curve"].read_text())
    import torch

    threads = torch.get_num_threads()
    # the cores left beside the environments: a rollout's forward pass is one frame per env, and on
    # a busy machine a thread pool waits for every thread at every operation (measured under load:
    # 520 ms per 120x160 frame with 2 threads, 20 ms with 1)
    torch.set_num_threads(max(1, (os.cpu_count() or 1) - n_envs))
    existed = {name: path.exists() for name, path in {**files, "out": out}.items()}
    venv = make_vec_env(cfg, env_kwargs, n_envs, s.seed)
    interrupted: BaseException | None = None
    failed = False
    try:
        model = _make_model(algo, venv, s, files, mtype, options, prep, init_model)
        trainer = _Trainer(model, cfg, out, files, meta, s, eval_tracks, curve, progress, on_event)
        remaining = max(0, s.timesteps - model.num_timesteps) if s.resume else s.timesteps
        try:
            with handling(STOP_SIGNALS, _stopped):  # SIGTERM / SIGHUP stop as Ctrl-C does
                model.learn(total_timesteps=remaining, callback=trainer.callback(),
                            reset_num_timesteps=not s.resume)
        except (KeyboardInterrupt, VehicleStopped) as exc:
            interrupted = exc
            logger.warning("rl train: stopped by %s at %d steps", "Ctrl-C" if isinstance(exc, KeyboardInterrupt)
                           else exc.signal_name, model.num_timesteps)
        except BaseException:
            failed = True
            raise
        finally:
            trainer.close_bar()
            if not failed:
                model.save(files["state"])
        if not interrupted and (not curve["evaluations"]
                                or curve["evaluations"][-1]["timesteps"] != model.num_timesteps):
            trainer.evaluate()
    except BaseException:
        failed = True
        raise
    finally:
        _close(venv)
        torch.set_num_threads(threads)
        files["eval"].unlink(missing_ok=True)
        if not failed:
            _write_curve(files, curve)
        elif curve["best"] is None:  # a failed run that kept no pilot leaves nothing behind
            for name, path in {**files, "out": out}.items():
                if not existed[name]:
                    path.unlink(missing_ok=True)
    if curve["best"] is not None:
        logger.info("rl train: best pilot %s (%s at %d steps)", out, describe_best(curve["best"]),
                    curve["best"]["timesteps"])
    if interrupted is not None:
        raise interrupted
    return curve


def _starting_point(cfg: Any, s: RLSettings, algo: str, mtype: str,
                    image_shape: tuple[int, int, int]) -> tuple[Any, dict[str, Any], Any]:
    """(the --init pilot or None, the network's options, the preprocessing) the policy starts from."""
    from parts.pilots.modelfile import load_model
    from parts.pilots.preprocess import Preprocess, preprocess_from_config
    from training.rl import model_options

    init_model = None
    options = model_options(mtype, s.throttle)
    if s.init:
        init_model, init_meta = load_model(s.init)
        if init_model.type_name != mtype:
            raise UserError(f"--init {s.init} is a {init_model.type_name!r} pilot; {algo} "
                            f"{'with' if s.throttle is not None else 'without'} --throttle trains a {mtype!r} "
                            f"network: train the pilot with --type {mtype}")
        prep = Preprocess.from_dict(init_meta["preprocess"])
        options = {**init_model.options, "dropout": 0.0}
        if mtype == "inferred":
            options.update(model_options(mtype, s.throttle))
    else:
        prep = preprocess_from_config(cfg, mtype, image_shape=image_shape)
    if prep.lanes is not None:
        raise UserError("rl train does not take the lane image (the lanes model type)")
    return init_model, options, prep


def _pilot_meta(cfg: Any, s: RLSettings, prep: Any, image_shape: tuple[int, int, int], tracks: list[int],
                eval_tracks: list[int], n_envs: int) -> dict[str, Any]:
    """What the kept pilot's file says about its training."""
    from parts.pilots.compat import camera_meta

    return {"preprocess": {**prep.to_dict(), "image_shape": list(image_shape)}, "camera": camera_meta(cfg),
            "datasets": [], "transfer": str(s.init) if s.init else None, "comment": s.comment,
            "training": {"method": "rl", **{k: list(v) if isinstance(v, tuple) else v for k, v in asdict(s).items()
                                            if k not in ("extra", "comment")},
                         "tracks": tracks, "eval_tracks": eval_tracks, "envs": n_envs,
                         "reward": _reward_name(s.reward)}}


def _make_model(algo: str, venv: Any, s: RLSettings, files: dict[str, Path], mtype: str, options: dict[str, Any],
                prep: Any, init_model: Any) -> Any:
    """The SB3 algorithm on ``venv``: resumed from its saved state, or new (from the --init pilot's
    weights when given)."""
    from training.rl import load_pilot_weights, policy_kwargs

    Algo = _algorithm(algo)  # noqa: N806 - a class
    if s.resume:
        return _quiet_logger(Algo.load(files["state"], env=venv, device="cpu"))
    log_std = s.log_std_init if s.log_std_init is not None else (-0.5 if init_model is None else -1.6)
    # a fine-tuned actor keeps its own trunk: the critic's early, large value errors would
    # otherwise rewrite the behaviour-cloned features through the shared layers
    kwargs = policy_kwargs(algo, mtype, options, prep.normalize, log_std_init=log_std,
                           share_trunk=init_model is None)
    args: dict[str, Any] = {"learning_rate": s.learning_rate, "batch_size": s.batch_size, "gamma": s.gamma,
                            "seed": s.seed, "device": "cpu", "verbose": 0, "policy_kwargs": kwargs}
    if algo == "ppo":
        args.update(n_steps=s.n_steps, n_epochs=s.n_epochs, clip_range=s.clip_range, target_kl=s.target_kl)
    else:
        args.update(buffer_size=10_000, learning_starts=1_000)  # 10k frames of 120x160: 1.2 GB with next frames
    model = Algo("CnnPolicy", venv, **{**args, **s.extra})
    _quiet_logger(model)
    if init_model is not None:
        load_pilot_weights(model.policy, init_model, s.throttle_range)
    return model


def _quiet_logger(model: Any) -> Any:
    """Give ``model`` a logger that writes nothing: without one of its own, every learn() made an
    empty ``SB3-<date-time>`` folder in the temporary directory (our own log rows and curve say
    what the run did)."""
    from stable_baselines3.common.logger import Logger

    model.set_logger(Logger(folder=None, output_formats=[]))
    return model


def describe_best(row: dict[str, Any]) -> str:
    """An evaluation row in words, laps beside autonomy: "autonomy 100.0 %, 2 laps (100 % of the laps
    asked), mean lap 14.2 s"."""
    lap = f", mean lap {row['mean_lap_s']:.1f} s" if row.get("mean_lap_s") is not None else ""
    share = row.get("completion")
    driven = f" ({share:.0%} of the laps asked)" if share is not None else ""
    return f"autonomy {row['autonomy']:.1f} %, {row.get('laps_completed') or 0} laps{driven}{lap}"


def _close(venv: Any) -> None:
    """Close the environments; a worker process that is already gone is not an error of its own."""
    try:
        venv.close()
    except (EOFError, BrokenPipeError, ConnectionError) as exc:
        logger.debug("rl train: an environment worker had already ended: %r", exc)


def _reward_name(reward: str | None) -> str:
    """What the pilot's metadata says of the reward: a file's absolute path or a built-in's name."""
    from parts.sim.reward import BUILTIN_REWARDS

    if reward is None:
        return "default"
    if reward in BUILTIN_REWARDS and not Path(reward).is_file():
        return reward
    return str(Path(reward).resolve())


def _stopped(signum: int, _frame: Any) -> None:
    raise VehicleStopped(signum, signal.Signals(signum).name)


class _Trainer:
    """The callback's work: progress, periodic closed-loop evaluation, the best pilot."""

    def __init__(self, model: Any, cfg: Any, out: Path, files: dict[str, Path], meta: dict[str, Any],
                 s: RLSettings, eval_tracks: list[int], curve: dict[str, Any], progress: bool,
                 on_event: Callable[[dict[str, Any]], None] | None) -> None:
        self.model, self.cfg, self.out, self.files, self.meta, self.s = model, cfg, out, files, meta, s
        self.eval_tracks, self.curve, self.on_event = eval_tracks, curve, on_event
        self.next_eval = (model.num_timesteps // s.eval_every + 1) * s.eval_every if s.eval_every else math.inf
        self.started = time.perf_counter()
        self.steps0 = model.num_timesteps
        # PPO's rollouts are n_steps per env (a row each); an off-policy algorithm's are one step
        self.row_steps = 0 if s.algo.lower() == "ppo" else ROW_STEPS
        self.throttle_range = s.throttle_range
        self.warming = model.num_timesteps < s.vf_warmup
        if self.warming:
            from training.rl import freeze_actor

            freeze_actor(model.policy, True)
            logger.info("rl train: value-function warm-up: only the critic learns for the first %d steps",
                        s.vf_warmup)
        self.bar = None
        if progress:
            from tqdm import tqdm

            self.bar = tqdm(total=s.timesteps, initial=model.num_timesteps, unit="step", desc="rl train")

    def callback(self) -> Any:
        from stable_baselines3.common.callbacks import BaseCallback

        trainer = self

        class _Callback(BaseCallback):
            def _on_step(self) -> bool:
                return trainer.on_step(self.locals.get("infos", ()))

            def _on_rollout_end(self) -> None:
                trainer.on_rollout_end()

        return _Callback()

    def episode_stats(self) -> tuple[float | None, float | None]:
        buf = self.model.ep_info_buffer or []
        if not buf:
            return None, None
        return float(np.mean([e["r"] for e in buf])), float(np.mean([e["l"] for e in buf]))

    def on_step(self, infos: Any = ()) -> bool:
        for info in infos:
            if "error" in info:  # a user's error in an environment (see _ReportErrors)
                raise UserError(info["error"])
        if self.bar is not None:
            self.bar.update(self.model.num_timesteps - self.bar.n)
        if self.model.num_timesteps >= self.next_eval:
            self.next_eval += self.s.eval_every
            self.evaluate()
        return True

    def on_rollout_end(self) -> None:
        # the update that follows learns from this rollout: the actor joins once it has steps past the warm-up
        if self.warming and self.model.num_timesteps > self.s.vf_warmup:
            from training.rl import freeze_actor

            freeze_actor(self.model.policy, False)
            self.warming = False
            logger.info("rl train: value-function warm-up done at %d steps: the actor learns", self.model.num_timesteps)
        steps = int(self.model.num_timesteps)
        if self.curve["rollouts"] and steps - self.curve["rollouts"][-1]["timesteps"] < self.row_steps:
            return  # SAC's "rollouts" are one step each: a row (and a log line) per ROW_STEPS steps
        reward, length = self.episode_stats()
        elapsed = time.perf_counter() - self.started
        fps = (self.model.num_timesteps - self.steps0) / elapsed if elapsed > 0 else 0.0
        row = {"timesteps": int(self.model.num_timesteps), "mean_reward": reward, "mean_length": length,
               "fps": round(fps, 1), "wall_s": round(elapsed, 1)}
        self.curve["rollouts"].append(row)
        if self.bar is not None:
            if reward is not None:
                self.bar.set_postfix(ep_rew=f"{reward:.2f}", ep_len=f"{length:.0f}")
        else:
            logger.info("rl train: %d steps, episode reward %s, length %s, %.0f steps/s", row["timesteps"],
                        "-" if reward is None else f"{reward:.3f}", "-" if length is None else f"{length:.0f}", fps)
        if self.on_event is not None:
            self.on_event({"event": "rollout", **row})

    def evaluate(self) -> dict[str, Any]:
        """Export the actor, drive it on the held-out tracks, keep it at ``out`` when best."""
        from training.rl import export_pilot
        from vehicle.app.evaluate import evaluate

        steps = int(self.model.num_timesteps)
        export_pilot(self.model.policy, self.files["eval"], self.meta, self.throttle_range)
        report = evaluate(str(self.files["eval"]), self.eval_tracks, self.s.eval_laps, cfg=self.cfg)
        o = report["overall"]
        reward, length = self.episode_stats()
        # a pilot that stands still never leaves the road (100 % autonomy): the score weighs autonomy
        # by the share of the laps it drove (parts.sim.metrics.score)
        row = {"timesteps": steps, "score": o["score"], "completion": o["completion"],
               "autonomy": o["autonomy"], "laps_completed": o["laps_completed"],
               "mean_lap_s": o["mean_lap_s"], "mean_speed": o["mean_speed"], "mean_abs_cte": o["mean_abs_cte"],
               "interventions": o["interventions"], "mean_reward": reward, "mean_length": length}
        self.curve["evaluations"].append(row)
        best = self.curve["best"]
        better = best is None or (row["score"] or 0.0, row["mean_speed"] or 0.0) > \
            (best.get("score", best["autonomy"]) or 0.0, best["mean_speed"] or 0.0)
        logger.info("rl train: evaluation at %d steps on tracks %s: %s%s", steps, self.eval_tracks, describe_best(row),
                    " (best so far: kept)" if better else "")
        if better:
            self.curve["best"] = row
            meta = {**self.meta, "created": datetime.now(UTC).isoformat(timespec="seconds"),
                    "metrics": {"rl_timesteps": steps, "eval_tracks": self.eval_tracks,
                                "eval_laps": self.s.eval_laps, **{k: v for k, v in row.items() if k != "timesteps"}}}
            export_pilot(self.model.policy, self.out, meta, self.throttle_range)
            _register(self.out, meta)
        _write_curve(self.files, self.curve)
        if self.on_event is not None:
            self.on_event({"event": "evaluation", **row, "best": better})
        return row

    def close_bar(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _register(path: Path, meta: dict[str, Any]) -> None:
    try:
        from training.model_db import register_model

        register_model(path, {**meta, "type": meta.get("type") or _type_of(path)}, comment=meta.get("comment"))
    except Exception as exc:  # the model is written; a db problem must not lose it
        logger.warning("rl pilot saved but not registered: %s", exc)


def _type_of(path: Path) -> str | None:
    from parts.pilots.modelfile import read_meta

    return read_meta(path).get("model", {}).get("type")


def _write_curve(files: dict[str, Path], curve: dict[str, Any]) -> None:
    files["curve"].parent.mkdir(parents=True, exist_ok=True)
    files["curve"].write_text(json.dumps(curve, indent=1))
    if curve["rollouts"]:
        try:
            plot_curve(curve, files["plot"])
        except ImportError:
            logger.warning("matplotlib is not installed: no learning-curve plot")


def plot_curve(curve: dict[str, Any], path: Path, title: str = "") -> None:
    """The learning curve: mean episode reward per rollout, and held-out autonomy per evaluation."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    rows = [r for r in curve["rollouts"] if r["mean_reward"] is not None]
    ax.plot([r["timesteps"] for r in rows], [r["mean_reward"] for r in rows], color="tab:blue")
    ax.set_xlabel("environment steps")
    ax.set_ylabel("mean episode reward (training)", color="tab:blue")
    if curve["evaluations"]:
        ax2 = ax.twinx()
        ev = curve["evaluations"]
        ax2.plot([r["timesteps"] for r in ev], [r["autonomy"] for r in ev], "o-", color="tab:red")
        ax2.set_ylabel("autonomy on held-out tracks, %", color="tab:red")
        ax2.set_ylim(0, 105)
    ax.set_title(title or "vehicle rl train")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
