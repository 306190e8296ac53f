"""``vehicle rl``: reinforcement learning in the built-in simulator (docs/rl.md).

    vehicle rl train [--car DIR] [--model models/rl.pt] [--algo ppo|sac] [--steps 100000] [--envs N]
                     [--tracks 1,2,3] [--eval-tracks 101,102,103] [--eval-every 20000] [--eval-laps 1]
                     [--reward reward.py|speed] [--throttle 0.3 | --throttle-range 0.2,0.8]
                     [--init models/bc.pt [--vf-warmup 2048] [--log-std-init -1.6] [--target-kl 0.02]]
                     [--resume] [--seed 0]
    vehicle rl reward-check reward.py [--car DIR]

The best pilot (highest autonomy over the laps driven on the held-out tracks) is an ordinary model file: drive it with
``manage.py drive --model``, evaluate it with ``vehicle sim eval``, export it with ``vehicle models
export``. Ctrl-C keeps the best and the training state; ``--resume`` goes on from there.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from vehicle.app.carconfig import add_car_options, load_for_command
from vehicle.errors import UserError


def _seeds(text: str) -> list[int]:
    try:
        seeds = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"track seeds must be comma-separated integers, got {text!r}") from None
    if not seeds:
        raise argparse.ArgumentTypeError("give at least one track seed")
    return seeds


def _range(text: str) -> tuple[float, float]:
    from parts.sim.gym_env import check_throttle_range

    try:
        low, high = (float(v) for v in text.split(","))
        result = check_throttle_range((low, high))
    except ValueError:
        raise argparse.ArgumentTypeError(f"give LOW,HIGH with -1 <= LOW < HIGH <= 1, e.g. 0.2,0.8; "
                                         f"got {text!r}") from None
    assert result is not None
    return result


def register(subparsers: Any) -> None:
    """Add ``vehicle rl train`` and ``vehicle rl reward-check``."""
    fmt = argparse.ArgumentDefaultsHelpFormatter
    parser = subparsers.add_parser("rl", help="reinforcement learning in the built-in simulator",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="rl_command", metavar="SUBCOMMAND", required=True)
    p = sub.add_parser("train", help="train a pilot with PPO or SAC (stable-baselines3)", formatter_class=fmt)
    add_car_options(p)
    p.add_argument("--model", default=None, help="pilot file to keep the best policy in (default: "
                   "<MODELS_PATH>/rl_<algo>.pt)")
    p.add_argument("--algo", choices=("ppo", "sac"), default="ppo", help="stable-baselines3 algorithm")
    p.add_argument("--steps", type=int, default=100_000, help="environment steps in all")
    p.add_argument("--envs", type=int, default=0, help="environments, one process each (0: one per core)")
    p.add_argument("--tracks", type=_seeds, help="training track seeds (default SIM_TRACK_SEEDS)")
    p.add_argument("--eval-tracks", type=_seeds, help="held-out track seeds (default SIM_EVAL_TRACK_SEEDS)")
    p.add_argument("--eval-every", type=int, default=20_000, help="steps between evaluations (0: at the end only)")
    p.add_argument("--eval-laps", type=int, default=1, help="laps per held-out track in an evaluation")
    p.add_argument("--reward", help="Python file defining reward_function(params), or a built-in: default "
                   "(speed along the track weighted by closeness to the centre), speed (that times the speed: "
                   "pays for driving fast)")
    p.add_argument("--throttle", type=float, help="steer only, at this fixed throttle (PPO)")
    p.add_argument("--throttle-range", type=_range, metavar="LOW,HIGH",
                   help="the policy's throttle action [-1, 1] spans LOW..HIGH (PPO; e.g. 0.2,0.8: exploration "
                   "neither reverses nor floors it); the pilot file clamps its throttle to it")
    p.add_argument("--laps", type=int, default=1, help="laps that end a training episode")
    p.add_argument("--max-steps", type=int, help="steps before an episode is truncated (default 60 s per lap)")
    p.add_argument("--draws", type=int, default=1, help="randomisation draws per track (with SIM_RANDOMIZE)")
    p.add_argument("--init", help="start from this behaviour-cloned pilot (same type: linear for PPO, "
                   "inferred with --throttle, linear_tanh for SAC)")
    p.add_argument("--resume", action="store_true", help="go on from the training state beside --model")
    p.add_argument("--seed", type=int, default=0, help="seed of the environments and the network")
    p.add_argument("--n-steps", type=int, default=256, help="PPO: steps per environment per update")
    p.add_argument("--batch-size", type=int, default=64, help="minibatch size")
    p.add_argument("--epochs", type=int, default=4, help="PPO: passes over each rollout")
    p.add_argument("--lr", type=float, default=3e-4, help="learning rate (fine-tuning: try 5e-5)")
    p.add_argument("--gamma", type=float, default=0.99, help="discount factor per step")
    p.add_argument("--clip-range", type=float, default=0.2, help="PPO: clip range of the probability ratio")
    p.add_argument("--target-kl", type=float, help="PPO: end an update's epochs once the KL to the policy "
                   "that collected the rollout passes this (fine-tuning: e.g. 0.02)")
    p.add_argument("--log-std-init", type=float, help="PPO: log of the starting exploration std "
                   "(default -0.5; -1.6 with --init, std 0.2, so the pilot's driving is not drowned in noise)")
    p.add_argument("--vf-warmup", type=int, default=0, help="PPO: steps during which only the critic learns "
                   "(fine-tuning: a critic that knows the pilot's values before the actor moves)")
    p.add_argument("--comment", default="", help="comment stored with the model")
    p.add_argument("--no-progress", action="store_true", help="log lines instead of a progress bar")
    p.set_defaults(func=_cmd_train)

    c = sub.add_parser("reward-check", help="call a reward file on a short drive and print its rewards")
    add_car_options(c)
    c.add_argument("reward", help="Python file defining reward_function(params)")
    c.add_argument("--steps", type=int, default=100, help="steps driven by the expert")
    c.set_defaults(func=_cmd_check)


def _cmd_train(args: argparse.Namespace) -> int:
    from vehicle.app.rl_train import RLSettings, describe_best, train_rl

    cfg = load_for_command(args)
    if args.steps < 1 or args.envs < 0 or args.eval_every < 0 or args.eval_laps < 1 or args.laps < 1:
        raise UserError("--steps, --eval-laps and --laps must be >= 1, --envs and --eval-every >= 0")
    if args.throttle is not None and not -1 <= args.throttle <= 1:
        raise UserError(f"--throttle must be in [-1, 1], got {args.throttle}")
    if args.vf_warmup < 0 or not 0 < args.gamma <= 1 or args.clip_range <= 0:
        raise UserError("--vf-warmup must be >= 0, --gamma in (0, 1], --clip-range > 0")
    out = Path(args.model) if args.model else cfg.path("MODELS_PATH") / f"rl_{args.algo}.pt"
    s = RLSettings(algo=args.algo, timesteps=args.steps, envs=args.envs, tracks=args.tracks,
                   eval_tracks=args.eval_tracks, eval_every=args.eval_every, eval_laps=args.eval_laps,
                   reward=args.reward, throttle=args.throttle, throttle_range=args.throttle_range,
                   laps=args.laps, max_steps=args.max_steps,
                   randomize_draws=args.draws, init=args.init, resume=args.resume, seed=args.seed,
                   n_steps=args.n_steps, batch_size=args.batch_size, n_epochs=args.epochs, learning_rate=args.lr,
                   gamma=args.gamma, clip_range=args.clip_range, target_kl=args.target_kl,
                   log_std_init=args.log_std_init, vf_warmup=args.vf_warmup, comment=args.comment)
    curve = train_rl(cfg, out, s, progress=not args.no_progress)
    best = curve["best"]
    tracks = s.eval_tracks or cfg.SIM_EVAL_TRACK_SEEDS
    if best is not None:
        print(f"best pilot {out}: {describe_best(best)} on tracks "  # noqa: T201 - the command's output
              f"{tracks} at {best['timesteps']} steps")
        if not best.get("score"):
            print("it has not driven its evaluation laps yet: train longer, or check the reward")  # noqa: T201
    return 0


def _cmd_check(args: argparse.Namespace) -> int:
    """Drive the expert for a few steps and print the rewards the file gives (catches errors early)."""
    from parts.sim.expert import Expert
    from parts.sim.gym_env import TrackEnv

    cfg = load_for_command(args)
    env = TrackEnv(cfg, reward=args.reward, tracks=cfg.SIM_TRACK_SEEDS[:1])
    env.reset(seed=0)
    expert = Expert.from_config(cfg, env.sim)
    rewards = []
    for _ in range(args.steps):
        angle, throttle = expert.run()[:2]
        _, r, term, trunc, _ = env.step([angle, throttle])
        rewards.append(r)
        if term or trunc:
            break
    print(f"{args.reward}: {len(rewards)} steps, reward total {sum(rewards):.3f}, "  # noqa: T201
          f"min {min(rewards):.3f}, max {max(rewards):.3f}")
    return 0
