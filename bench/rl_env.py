"""Benchmark of the Gymnasium environment: environment steps per second, in one run,
  * ``vehicle/Track-v0`` in this process (one env);
  * ``vehicle/Track-v0`` vectorised, one process per core (gymnasium's AsyncVectorEnv);
  * gym-donkeycar 1.3.1's client (``donkey-generated-track-v0``, exe_path "remote") driving
    ``vehicle sim serve`` over the Donkey TCP protocol, what RL against the Donkey simulator runs
    on (real time: the server's telemetry rate, --hz; 20 Hz is the Donkey simulator's own).

Every environment takes the same seeded random actions (steering uniform in [-0.3, 0.3], throttle
0.3) and is reset when its episode ends. gym-donkeycar is not on PyPI past 1.0.13 (2019, old gym
API): the source of 1.3.1 is read from ``.bench/gym-donkeycar`` (``git archive`` of
tawnkramer/gym-donkeycar, gym_donkeycar/ only; its dependencies gymnasium, numpy, pillow are in
the venv).

Setup (once): git clone https://github.com/tawnkramer/gym-donkeycar /tmp/gym-donkeycar &&
mkdir -p .bench/gym-donkeycar && git -C /tmp/gym-donkeycar archive HEAD gym_donkeycar | tar -x -C .bench/gym-donkeycar

Usage: .venv/bin/python bench/rl_env.py [--seconds 20] [--hz 20,1000]
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import socket
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, ".bench", "gym-donkeycar"))
ENV = {**os.environ, "PYTHONPATH": ROOT + os.pathsep + os.environ.get("PYTHONPATH", "")}

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

from vehicle.config import Config  # noqa: E402


def actions(n: int, k: int = 1) -> np.ndarray:
    rng = np.random.default_rng(0)
    a = np.empty((n, k, 2), np.float32)
    a[..., 0] = rng.uniform(-0.3, 0.3, (n, k))
    a[..., 1] = 0.3
    return a


def ours_single(seconds: float, cfg: Config) -> float:
    import parts.sim.gym_env  # noqa: F401 - registers vehicle/Track-v0

    env = gym.make("vehicle/Track-v0", config=cfg, tracks=[1])  # one track: the steps, not track drawing
    env.reset(seed=0)
    acts, n, t0 = actions(100_000), 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        _, _, term, trunc, _ = env.step(acts[n % len(acts), 0])
        n += 1
        if term or trunc:
            env.reset()
    return n / (time.perf_counter() - t0)


def ours_vector(seconds: float, cfg: Config, n_envs: int) -> float:
    import parts.sim.gym_env  # noqa: F401

    env = gym.make_vec("vehicle/Track-v0", num_envs=n_envs, vectorization_mode="async", config=cfg, tracks=[1])
    env.reset(seed=0)  # autoreset: an ended episode resets on the next step
    acts, n, t0 = actions(100_000, n_envs), 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        env.step(acts[n % len(acts)])
        n += 1
    rate = n * n_envs / (time.perf_counter() - t0)
    env.close()
    return rate


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_listening(port: int, server: subprocess.Popen[bytes], timeout: float = 120.0) -> None:
    """Wait until the server accepts connections (it draws its track first)."""
    t0 = time.time()
    while time.time() - t0 < timeout:
        if server.poll() is not None:
            raise RuntimeError("vehicle sim serve exited")
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1.0).close()
            time.sleep(0.5)  # that probe was a client: let the server see it leave
            return
        except OSError:
            time.sleep(0.2)
    raise RuntimeError("vehicle sim serve did not listen")


def gym_donkeycar(seconds: float, hz: float) -> float:
    try:
        import gym_donkeycar  # noqa: F401 - registers the donkey-* environments
    except ImportError:
        sys.exit("gym-donkeycar 1.3.1 is not in .bench/gym-donkeycar: see the setup in bench/rl_env.py")

    port = free_port()
    server = subprocess.Popen([sys.executable, "-m", "vehicle", "sim", "serve", "--port", str(port), "--tracks", "1",
                               "--hz", str(hz), "--car", ROOT], env=ENV, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    try:
        wait_listening(port, server)
        env = gym.make("donkey-generated-track-v0",
                       conf={"exe_path": "remote", "host": "127.0.0.1", "port": port, "max_cte": 0.4,
                             "log_level": logging.WARNING})
        env.reset()
        acts, n, t0 = actions(100_000), 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            _, _, term, trunc, _ = env.step(acts[n % len(acts), 0])
            n += 1
            if term or trunc:
                env.reset()
        rate = n / (time.perf_counter() - t0)
        env.close()
        return rate
    finally:
        server.terminate()
        server.wait(10)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seconds", type=float, default=20.0, help="seconds per measurement")
    p.add_argument("--hz", default="20", help="comma-separated telemetry rates of vehicle sim serve ('none': "
                   "skip gym-donkeycar)")
    p.add_argument("--envs", type=int, default=os.cpu_count() or 1, help="vectorised environments")
    p.add_argument("--camera", default="160x120", help="camera WxH (a larger frame makes a step dearer)")
    args = p.parse_args()
    w, h = (int(v) for v in args.camera.split("x"))
    cfg = Config.defaults(SIM_REALTIME=False, SIM_CAMERA_W=w, SIM_CAMERA_H=h)
    out: dict[str, float] = {"ours_single": ours_single(args.seconds, cfg),
                             f"ours_vector_{args.envs}": ours_vector(args.seconds, cfg, args.envs)}
    print(out, flush=True)  # noqa: T201
    for hz in (float(h) for h in args.hz.split(",") if args.hz != "none"):
        out[f"gym_donkeycar_serve_{hz:g}hz"] = gym_donkeycar(args.seconds, hz)
    print(json.dumps({k: round(v, 1) for k, v in out.items()}, indent=1))  # noqa: T201
    with open("/proc/loadavg") as f:
        print("load average:", f.read().split()[:3])  # noqa: T201


if __name__ == "__main__":
    main()
