"""DAgger (dataset aggregation) in the built-in simulator: the pilot drives, the expert labels.

Behavioural cloning learns from the states the expert visits; the pilot's own small errors take it
to states the expert never showed (compounding errors). DAgger (Ross, Gordon & Bagnell, 2011)
closes that gap::

    round 0: the pilot trained on the expert's demonstrations (``--transfer``, or trained first)
    round i: the pilot drives the training tracks under a new randomisation draw; the expert labels
             every frame with what it would have done (steering and throttle); the frames join the
             data as an ordinary tub; the pilot is fine-tuned from round i-1's weights on all of it;
             it is evaluated on unseen tracks under hidden draws (mean and worst per theme).

Who drives a roll-out frame: the pilot, except with probability ``beta_i = beta * 0.5**(i-1)``
the expert (the β-mixing of the paper, per frame). The default ``beta`` is 0 (pure pilot
roll-outs): round 0 already is the paper's β = 1 round (the expert's own demonstrations), and
every frame the pilot drives is a state its own errors lead to, which is what the data lacks.
When the pilot leaves the road, the simulator re-centres the car where it left (the person who
picks the car up), so no frame is spent off the road where the expert's label means nothing.

Records: ``user/angle`` and ``user/throttle`` are the expert's label, ``pilot/angle`` and
``pilot/throttle`` what the pilot commanded, ``user/mode`` who drove ("local": the pilot,
"user": the expert) and ``user/correction`` is True on frames the pilot drove: a correction label
(docs/data-format.md). Training keeps correction records whatever TRAIN_MODES says.

Ctrl-C keeps every finished round (tub, model, table); the simulated car stops in the loop's safe
path (actuators to neutral), and the table so far is written before the interrupt goes on.
"""

from __future__ import annotations

import json
import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

logger = logging.getLogger(__name__)

#: roll-out round i is randomised with seed ROLLOUT_DRAW_BASE + i (never a hidden evaluation draw)
ROLLOUT_DRAW_BASE = 100
#: roll-out frames per track at least (~10 s, about a lap): the car starts every track standing, and
#: with a few dozen frames per track most labels were the expert accelerating from standstill (a
#: throttle a pilot that cannot see its speed learns as "always faster": measured, docs/pilot.md)
FRAMES_PER_TRACK = 200
#: what a DAgger record holds (memory key, tub type)
RECORD_FIELDS: tuple[tuple[str, str], ...] = (
    ("cam/image_array", "image_array"),
    ("user/angle", "float"),
    ("user/throttle", "float"),
    ("user/mode", "str"),
    ("user/correction", "boolean"),
    ("pilot/angle", "float"),
    ("pilot/throttle", "float"),
    ("cam/timestamp", "float"),
    ("sim/cte", "float"),
    ("sim/speed", "float"),
    ("sim/track", "int"),
)


@dataclass
class DaggerPlan:
    """What a DAgger run does (the options of ``vehicle train --dagger``)."""

    rounds: int
    records: int = 2000  # roll-out frames per round
    beta: float = 0.0  # probability the expert drives a frame in round 1, halved each round
    tracks: list[int] = field(default_factory=lambda: list(range(1, 65)))  # roll-out (training) tracks
    eval_tracks: list[int] = field(default_factory=lambda: [101, 102, 103, 104, 105])
    eval_draws: int = 3
    eval_themes: list[str] = field(default_factory=lambda: ["road", "indoor", "park"])
    laps: int = 2
    epochs: int | None = None  # fine-tuning epochs per round (None: MAX_EPOCHS)
    workers: int = 1  # evaluation processes
    max_time: float | None = None  # simulated seconds per evaluation track (None: SIM_EVAL_MAX_TIME or 60 s/lap)

    def check(self) -> None:
        """ValueError naming the bad option."""
        if self.rounds < 1:
            raise ValueError(f"--dagger {self.rounds}: give at least 1 round")
        if self.records < 10:
            raise ValueError(f"--dagger-records {self.records}: give at least 10 frames per round")
        if not 0.0 <= self.beta <= 1.0:
            raise ValueError(f"--dagger-beta {self.beta}: give a probability in [0, 1]")
        if not self.tracks or set(self.tracks) & set(self.eval_tracks):
            raise ValueError(f"roll-out tracks {sorted(set(self.tracks) & set(self.eval_tracks))} are also "
                             "evaluation tracks: evaluate on tracks the pilot never drove")
        if self.eval_draws < 1 or self.laps < 1:
            raise ValueError("evaluation needs at least 1 draw and 1 lap")

    def tracks_of(self, round_: int) -> list[int]:
        """The roll-out tracks of round ``round_`` (1-based): at least FRAMES_PER_TRACK frames each,
        the next ones of ``tracks`` in every round (round-robin), so the rounds see other tracks."""
        k = max(1, min(len(self.tracks), self.records // FRAMES_PER_TRACK))
        start = (round_ - 1) * k
        return [self.tracks[(start + j) % len(self.tracks)] for j in range(k)]

    def beta_of(self, round_: int) -> float:
        """β of roll-out round ``round_`` (1-based)."""
        return self.beta * 0.5 ** (round_ - 1)


class Labeller:
    """Part: the expert's command is the label; who drives this frame is drawn (β-mixing).

    In: ``expert/angle``, ``expert/throttle`` (the expert's command for this state), ``pilot/angle``.
    Out: ``user/mode`` ("user" when the expert drives, else "local"), ``user/angle`` and
    ``user/throttle`` (the label), ``user/correction`` (the pilot drove: a correction label),
    ``recording`` (always). Keeps how far the pilot's steering was from the label.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("expert/angle", "expert/throttle", "pilot/angle")
    OUTPUTS: ClassVar[tuple[str, ...]] = ("user/mode", "user/angle", "user/throttle", "user/correction",
                                          "recording")

    def __init__(self, beta: float, seed: int = 0) -> None:
        self.beta = float(beta)
        self.rng = np.random.default_rng([seed & 0xFFFFFFFF, 0xDA66])
        self.frames = self.expert_frames = 0
        self.abs_error = 0.0  # sum of |pilot angle - expert angle| over the pilot's frames

    def run(self, angle: float, throttle: float, pilot_angle: Any) -> tuple[str, float, float, bool, bool]:
        expert_drives = self.beta > 0 and self.rng.random() < self.beta
        self.frames += 1
        if expert_drives:
            self.expert_frames += 1
        elif pilot_angle is not None and math.isfinite(float(pilot_angle)):
            self.abs_error += abs(float(pilot_angle) - float(angle))
        return ("user" if expert_drives else "local"), float(angle), float(throttle), not expert_drives, True

    @property
    def mean_abs_error(self) -> float | None:
        """Mean |pilot steering - expert label| over the frames the pilot drove."""
        n = self.frames - self.expert_frames
        return round(self.abs_error / n, 4) if n else None


def rollout(cfg: Any, driver: Any, tub: Path, *, records: int, tracks: Sequence[int], draw: int, beta: float,
            seed: int = 0, add_parts: Callable[[Any], None] | None = None) -> dict[str, Any]:
    """One round's roll-out: ``driver`` (a pilot part) drives ``records`` frames spread over
    ``tracks`` (themes of SIM_THEME dealt in turn) under randomisation draw ``draw``; every frame is
    written to ``tub`` with the expert's label. ``add_parts(V)`` adds parts after the drive mode
    (tests: a fake actuator). Returns the roll-out's figures."""
    from parts.sim.expert import Expert
    from parts.sim.simulator import SimCar
    from vehicle import Vehicle
    from vehicle.app.assembly.camera import add_undistort
    from vehicle.app.assembly.drive import add_drive_mode, add_obstacle_stop, add_speed_limit
    from vehicle.app.assembly.tub import add_tub_writer
    from vehicle.app.evaluate import Lent
    from vehicle.app.record import WaitForTubWriter
    from vehicle.clock import SimulatedClock

    cfg = cfg.replace(SIM_RANDOMIZE=draw, SIM_REALTIME=False,
                      METADATA=[*cfg.METADATA, "source:dagger", f"tracks:{','.join(map(str, tracks))}",
                                f"randomize:{draw}", f"beta:{beta:g}"],
                      DATA_PATH=str(Path(tub).absolute()), AUTO_CREATE_NEW_TUB=False)
    sim = SimCar.from_config(cfg, seeds=list(tracks), reset_off_track=True, reset_to="nearest", realtime=False)
    if len(tracks) > 1:
        sim.switch_every = math.ceil(records / len(tracks))
    if callable(getattr(driver, "reset", None)):
        driver.reset()
    V = Vehicle(clock=SimulatedClock())
    V.add(sim)
    add_undistort(V, cfg, (cfg.SIM_CAMERA_W, cfg.SIM_CAMERA_H), "SIM_CAMERA_W x SIM_CAMERA_H")
    # the expert computes its command from the car's true state: the label, whoever drives
    V.add(Expert.from_config(cfg.replace(TRAIN_BEHAVIORS=False), sim),
          outputs=["expert/angle", "expert/throttle", "expert/mode", "expert/recording"])
    V.add(Lent(driver))  # the pilot runs on every frame (its command is recorded beside the label)
    labeller = Labeller(beta, seed)
    V.add(labeller)
    add_drive_mode(V, cfg)
    add_speed_limit(V, cfg)
    add_obstacle_stop(V, cfg)
    if add_parts is not None:
        add_parts(V)
    writer = add_tub_writer(V, cfg, inputs=[k for k, _ in RECORD_FIELDS], types=[t for _, t in RECORD_FIELDS])
    V.add(WaitForTubWriter(writer))
    V.start(rate_hz=cfg.DRIVE_LOOP_HZ, max_loop_count=records, log_summary=False)
    return {"tub": str(writer.path), "records": labeller.frames, "expert_frames": labeller.expert_frames,
            "interventions": sim.resets, "laps": sim.tracker.laps, "draw": draw, "beta": beta,
            "pilot_vs_expert_abs_angle": labeller.mean_abs_error}


def _round_model(model_path: Path, round_: int) -> Path:
    return model_path.with_name(f"{model_path.stem}_r{round_}{model_path.suffix}")


def _with_expert(summary: dict[str, Any], reference: dict[str, Any] | None) -> dict[str, Any]:
    """A round's per-theme summaries with round 0's expert reference (the expert does not change)."""
    if reference is None:
        return summary
    for theme, s in summary.items():
        ref = reference.get(theme) or {}
        s["expert_speed"], s["expert_autonomy"] = ref.get("expert_speed"), ref.get("expert_autonomy")
        pilot = s["mean"]["mean_speed"]
        s["speed_vs_expert_pct"] = (round(100.0 * pilot / s["expert_speed"], 1)
                                    if s["expert_speed"] and pilot is not None else None)
    return summary


def format_rounds(rounds: Sequence[dict[str, Any]]) -> str:
    """The round table: one row per round and theme (mean over the hidden draws and the worst).

    The score (autonomy x share of the asked laps driven; the worst draw is the lowest) comes before
    autonomy, with the share driven and the laps: autonomy alone reads 100 % for a car that stood still.
    """
    from vehicle.app.eval_draws import cell, driven_pct

    headers = ["round", "theme", "score mean", "worst (draw)", "driven % mean", "laps mean", "autonomy % mean",
               "worst", "interv. mean", "worst", "|cte| m mean", "speed % expert", "new records",
               "pilot-expert |angle|"]
    rows = []
    for r in rounds:
        for theme, s in r["by_theme"].items():
            m, w = s["mean"], s["worst"]
            roll = r.get("rollout") or {}
            rows.append([str(r["round"]), theme, cell(m.get("score"), "{:.1f}"),
                         f"{cell(w.get('score'), '{:.1f}')} ({w['randomize']})",
                         cell(driven_pct(m.get("completion")), "{:.0f}"), cell(m.get("laps_completed"), "{:.1f}"),
                         cell(m["autonomy"], "{:.1f}"), cell(w["autonomy"], "{:.1f}"),
                         cell(m["interventions"], "{:.1f}"), str(w["interventions"]),
                         cell(m["mean_abs_cte"], "{:.3f}"), cell(s.get("speed_vs_expert_pct"), "{:.0f}"),
                         str(roll.get("records", 0)), cell(roll.get("pilot_vs_expert_abs_angle"), "{:.3f}")])
    widths = [max(len(x[i]) for x in [headers, *rows]) for i in range(len(headers))]
    lines = ["  ".join(h.rjust(wd) for h, wd in zip(headers, widths, strict=True)),
             "  ".join("-" * wd for wd in widths)]
    lines += ["  ".join(c.rjust(wd) for c, wd in zip(x, widths, strict=True)) for x in rows]
    return "\n".join(lines)


def run_dagger(cfg: Any, base_tubs: Sequence[str], model_path: Path, plan: DaggerPlan, *,
               start_model: Path | None = None, train_options: dict[str, Any] | None = None,
               say: Callable[[str], None] = logger.info,
               add_parts: Callable[[Any], None] | None = None) -> dict[str, Any]:
    """Run ``plan.rounds`` DAgger rounds; returns ``{"rounds": [...], "table": path, "model": last}``.

    Round 0 is ``start_model`` (or a model trained on ``base_tubs`` first). Round i writes the tub
    ``DATA_PATH/dagger_<stem>_r<i>`` and the model ``<stem>_r<i>.pt`` next to ``model_path``,
    fine-tuned from round i-1's weights (``transfer``) on the base tubs and every DAgger tub so far;
    the table (``<stem>.dagger.json``) is rewritten after every round, so Ctrl-C keeps what finished.
    """
    from vehicle.app.demo import train_or_stop
    from vehicle.app.eval_draws import evaluate_draws, hidden_draws
    from vehicle.app.evaluate import resolve_pilot

    plan.check()
    draws = hidden_draws(plan.eval_draws, cfg.SIM_RANDOMIZE)
    model_path = Path(model_path)
    model_path.parent.mkdir(parents=True, exist_ok=True)
    table_path = model_path.with_suffix(".dagger.json")
    options = dict(train_options or {})
    if plan.epochs is not None:
        options["epochs"] = plan.epochs
    rounds: list[dict[str, Any]] = []
    reference: dict[str, Any] | None = None
    tubs = [Path(cfg.path("DATA_PATH")) / f"dagger_{model_path.stem}_r{i}" for i in range(1, plan.rounds + 1)]
    taken = [str(p) for p in tubs if p.exists()]
    if taken:  # refused before any work, not after round 0's evaluation
        raise ValueError(f"{', '.join(taken)} exist(s) from an earlier run: move them away or write another --model")

    def save() -> None:
        table_path.write_text(json.dumps({"plan": plan.__dict__, "draws": draws, "rounds": rounds}, indent=1) + "\n")

    def evaluate_round(i: int, model: Path, roll: dict[str, Any] | None, train_s: float) -> None:
        nonlocal reference
        say(f"round {i}: evaluating {model.name} on tracks {plan.eval_tracks} in {', '.join(plan.eval_themes)} "
            f"under hidden draws {draws} ...")
        report = evaluate_draws(str(model), plan.eval_tracks, plan.laps, cfg=cfg, draws=draws,
                                themes=plan.eval_themes, expert=reference is None, workers=plan.workers,
                                max_time=plan.max_time)
        by_theme = _with_expert(report["by_theme"], reference)
        reference = reference or by_theme
        rounds.append({"round": i, "model": str(model), "rollout": roll, "rollout_and_training_s": round(train_s, 1),
                       "by_theme": by_theme})
        save()
        say(format_rounds(rounds[-1:]))

    current = Path(start_model) if start_model is not None else None
    dagger_tubs: list[str] = []
    try:
        t = time.perf_counter()
        if current is None:
            current = _round_model(model_path, 0)
            say(f"round 0: training {current.name} on {', '.join(map(str, base_tubs))} ...")
            train_or_stop(cfg, [Path(p) for p in base_tubs], current, comment="dagger round 0",
                          ends="DAgger ends here", **options)
        evaluate_round(0, current, None, time.perf_counter() - t)
        for i in range(1, plan.rounds + 1):
            t = time.perf_counter()
            tub = tubs[i - 1]
            beta = plan.beta_of(i)
            tracks = plan.tracks_of(i)
            say(f"round {i}: the pilot {current.name} drives {plan.records} frames on tracks "
                f"{','.join(map(str, tracks))} (draw {ROLLOUT_DRAW_BASE + i}, beta {beta:g}); the expert labels "
                f"every frame into {tub} ...")
            driver, _, owned = resolve_pilot(current, cfg)
            try:
                roll = rollout(cfg, driver, tub, records=plan.records, tracks=tracks,
                               draw=ROLLOUT_DRAW_BASE + i, beta=beta, seed=cfg.SIM_SEED + i, add_parts=add_parts)
            finally:
                if owned and callable(getattr(driver, "shutdown", None)):
                    driver.shutdown()
            dagger_tubs.append(roll["tub"])
            new = _round_model(model_path, i)
            data = [*base_tubs, *(p for p in dagger_tubs if not _covered(p, base_tubs))]
            say(f"round {i}: {roll['records']} frames, {roll['interventions']} interventions, pilot vs expert "
                f"|angle| {roll['pilot_vs_expert_abs_angle']}; fine-tuning {new.name} from {current.name} on "
                f"{len(data)} tub(s) ...")
            train_or_stop(cfg, [Path(p) for p in data], new, transfer=current, comment=f"dagger round {i}",
                          ends="DAgger ends here", **options)
            current = new
            evaluate_round(i, current, roll, time.perf_counter() - t)
    except KeyboardInterrupt:
        save()
        say(f"stopped by Ctrl-C: {len(rounds)} finished round(s) kept in {table_path}")
        raise
    say(f"DAgger: {plan.rounds} round(s); table in {table_path}")
    return {"rounds": rounds, "table": table_path, "model": current, "draws": draws}


def _covered(tub: str, bases: Sequence[str]) -> bool:
    """Whether ``tub`` is already read as part of one of ``bases`` (the tub itself or its folder)."""
    p = Path(tub).resolve()
    return any(p == Path(b).resolve() or p.parent == Path(b).resolve() for b in bases)
