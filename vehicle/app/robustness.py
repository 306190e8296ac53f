"""``vehicle sim robustness``: a pilot's quality as a distribution, not one training run's number.

A demo recipe (``vehicle demo --recipe plain|augmented|robust|materials``) is recorded, trained and
evaluated once per training seed and precision path (``vehicle demo --seed N --precision P
--draws D``, each run a subprocess with one torch thread, ``--jobs`` at a time, its output in
``OUT/runs/<name>.log``). Each run drives the unseen tracks in every theme under the hidden
randomisation draws (`vehicle sim eval --draws`); the protocol then reports per theme the mean
over every run and draw, the worst draw and the worst seed, with the laps driven beside autonomy
(a car that stands still has 100 % DAVE-2 autonomy but score 0: parts/sim/metrics.py, rank_key).

With ``--lanes`` the runs are ``vehicle demo --lanes`` (the ``lanes`` and ``behavior`` models,
commanded lane changes) and the report is per model (:mod:`vehicle.app.lanes_robustness`).

A run whose ``eval/result.json`` exists is finished and kept; a run folder without one (killed) is
removed and run again, so the command resumes where it was stopped.
"""

from __future__ import annotations

import contextlib
import logging
import os
import shlex
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, NamedTuple

import numpy as np

from vehicle.app.demo import RECIPES as DEMO_RECIPES

logger = logging.getLogger(__name__)

RECIPES = tuple(DEMO_RECIPES)  # vehicle.app.demo.RECIPES: plain, augmented, robust, materials, normed, grouped
#: the runs' name prefix (RunSpec.recipe) of ``--lanes``: vehicle demo --lanes has no recipes
LANES = "lanes"
PRECISIONS = ("fp32", "bf16")
#: a run's summary, relative to its folder (written last and atomically by ``vehicle demo``)
RESULT = Path("eval") / "result.json"
#: seconds a run has after SIGINT to keep what it has and exit before it is killed
STOP_GRACE_S = 30.0
#: seconds between checks of the running subprocesses
POLL_S = 0.5


class RunSpec(NamedTuple):
    """One training run of the protocol."""

    recipe: str
    seed: int
    precision: str

    @property
    def name(self) -> str:
        return f"{self.recipe}-s{self.seed}-{self.precision}"


@dataclass
class Protocol:
    """What ``vehicle sim robustness`` runs (None: the demo's default)."""

    out: Path
    recipe: str = "plain"
    seeds: list[int] = field(default_factory=lambda: [1, 2, 3])
    precisions: list[str] = field(default_factory=lambda: ["fp32"])
    draws: int = 3
    eval_tracks: list[int] | None = None
    laps: int | None = None
    records: int | None = None
    epochs: int | None = None
    train_tracks: list[int] | None = None
    jobs: int = 1
    lane_changes: int | None = None  # --lanes: lane changes commanded while recording

    @property
    def lanes(self) -> bool:
        """The runs are ``vehicle demo --lanes``."""
        return self.recipe == LANES

    def specs(self) -> list[RunSpec]:
        return [RunSpec(self.recipe, s, p) for s in self.seeds for p in self.precisions]

    def command_line(self) -> str:
        """The command that runs this protocol again (defaults written out)."""
        what = ["--lanes"] if self.lanes else ["--recipe", self.recipe]
        words = ["vehicle", "sim", "robustness", *what, "--seeds", _ints(self.seeds),
                 "--precisions", ",".join(self.precisions), "--draws", str(self.draws), *self.demo_options()]
        return shlex.join([*words, "--jobs", str(self.jobs), "--out", str(self.out)])

    def demo_options(self) -> list[str]:
        """The options given to every run's ``vehicle demo`` (those left at the demo's default are left out)."""
        words: list[str] = []
        for option, value in (("--eval-tracks", self.eval_tracks), ("--laps", self.laps),
                              ("--records", self.records), ("--epochs", self.epochs),
                              ("--train-tracks", self.train_tracks), ("--lane-changes", self.lane_changes)):
            if value is not None:
                words += [option, _ints(value) if isinstance(value, list) else str(value)]
        return words


def _ints(values: list[int]) -> str:
    return ",".join(map(str, values))


def say(text: str) -> None:
    print(text, flush=True)  # noqa: T201 - the command's own output


def demo_command(spec: RunSpec, folder: Path, protocol: Protocol) -> list[str]:
    """The ``vehicle demo`` subprocess of one run, with one torch thread."""
    cmd = [sys.executable, "-m", "vehicle.app.cli", "demo", "--out", str(folder), "--seed", str(spec.seed),
           "--precision", spec.precision, "--draws", str(protocol.draws), "--threads", "1", *protocol.demo_options()]
    return [*cmd, "--lanes"] if protocol.lanes else [*cmd, "--recipe", spec.recipe]


def child_env() -> dict[str, str]:
    """This environment, with this checkout first on PYTHONPATH (the runs use the same code) and one
    OpenMP/MKL thread per run (``--jobs`` runs share the cores)."""
    root = str(Path(__file__).resolve().parents[2])
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
    env.update(OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    return env


def pending_runs(specs: list[RunSpec], runs_dir: Path) -> list[RunSpec]:
    """The runs still to do: a finished run (its result file exists) is kept, an unfinished run's
    folder is removed (it is redone from the start)."""
    todo = []
    for spec in specs:
        folder = runs_dir / spec.name
        if (folder / RESULT).is_file():
            say(f"run {spec.name}: finished before ({folder / RESULT}), kept")
            continue
        if folder.exists():
            say(f"run {spec.name}: unfinished before, removed and run again")
            shutil.rmtree(folder)
        todo.append(spec)
    return todo


@contextlib.contextmanager
def sigterm_stops() -> Iterator[None]:
    """SIGTERM raises :class:`vehicle.errors.VehicleStopped` in the main thread (exit 143) while
    inside, so the runs are stopped as on Ctrl-C."""
    from vehicle.errors import VehicleStopped

    def handler(signum: int, frame: Any) -> None:
        raise VehicleStopped(signum, "SIGTERM")

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def stop_runs(running: dict[RunSpec, tuple[subprocess.Popen[bytes], IO[bytes], float]]) -> None:
    """Ctrl-C each running demo (its own stop path: it keeps what it trained, exits 130); kill
    those still running after :data:`STOP_GRACE_S`."""
    for spec, (proc, _, _) in running.items():
        say(f"run {spec.name}: stopping")
        with contextlib.suppress(ProcessLookupError):
            proc.send_signal(signal.SIGINT)
    deadline = time.monotonic() + STOP_GRACE_S
    for proc, log, _ in running.values():
        try:
            proc.wait(max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        log.close()


def run_all(specs: list[RunSpec], protocol: Protocol,
            command: Callable[[RunSpec, Path, Protocol], list[str]]) -> dict[str, int]:
    """Run ``specs`` as subprocesses, ``protocol.jobs`` at a time; returns each run's exit code.
    Ctrl-C or SIGTERM stops the running ones (:func:`stop_runs`) and is raised again."""
    runs_dir = protocol.out / "runs"
    runs_dir.mkdir(parents=True, exist_ok=True)
    queue = list(specs)
    running: dict[RunSpec, tuple[subprocess.Popen[bytes], IO[bytes], float]] = {}  # process, log, start time
    codes: dict[str, int] = {}
    env = child_env()
    try:
        with sigterm_stops():
            while queue or running:
                while queue and len(running) < protocol.jobs:
                    spec = queue.pop(0)
                    log = (runs_dir / f"{spec.name}.log").open("wb")
                    # a session of its own: a Ctrl-C at the terminal reaches the runs once, from here
                    proc = subprocess.Popen(command(spec, runs_dir / spec.name, protocol), stdout=log,
                                            stderr=subprocess.STDOUT, env=env, start_new_session=True)
                    running[spec] = (proc, log, time.perf_counter())
                    say(f"run {spec.name}: started (log {log.name})")
                for spec, (proc, log, started) in list(running.items()):
                    if proc.poll() is not None:
                        log.close()
                        del running[spec]
                        codes[spec.name] = proc.returncode
                        how = "finished" if proc.returncode == 0 else f"FAILED (exit {proc.returncode})"
                        say(f"run {spec.name}: {how} in {time.perf_counter() - started:.0f} s")
                time.sleep(POLL_S)
    except BaseException:
        stop_runs(running)
        raise
    return codes


def load_results(specs: list[RunSpec], runs_dir: Path) -> list[dict[str, Any]]:
    """The finished runs' summaries, each with its ``name``."""
    import json

    results = []
    for spec in specs:
        path = runs_dir / spec.name / RESULT
        if path.is_file():
            results.append({**json.loads(path.read_text()), "name": spec.name})
    return results


def _mean(values: list[Any]) -> float | None:
    values = [v for v in values if v is not None]
    return round(float(np.mean(values)), 3) if values else None


def draw_rows(results: list[dict[str, Any]], theme: str) -> list[dict[str, Any]]:
    """Every (run, hidden draw) of ``theme``: the draw's figures with the run's seed and precision
    and the laps it was asked to drive."""
    rows = []
    for r in results:
        asked = r["laps"] * len(r["eval_tracks"])
        for d in r["by_theme"][theme]["per_draw"]:
            rows.append({**d, "seed": r["seed"], "precision": r["precision"], "run": r["name"], "laps_asked": asked})
    return rows


def theme_summary(results: list[dict[str, Any]], theme: str) -> dict[str, Any]:
    """One theme over every run and draw: means, laps, the worst draw, the worst seed, interventions
    per run and speed against the expert's."""
    from vehicle.app.eval_draws import worst_index

    rows = draw_rows(results, theme)
    w = rows[worst_index(rows)]
    by_run = [r["by_theme"][theme] for r in results]
    ws = worst_index([s["mean"] for s in by_run])
    interventions = [sum(d["interventions"] or 0 for d in s["per_draw"]) for s in by_run]
    return {
        "runs": len(results), "draws": len(rows),
        "mean": {k: _mean([row.get(k) for row in rows])
                 for k in ("score", "autonomy", "completion", "mean_abs_cte", "mean_speed")},
        "laps_completed": sum(row["laps_completed"] or 0 for row in rows),
        "laps_asked": sum(row["laps_asked"] for row in rows),
        # draws where the car did not drive every lap asked: their autonomy is not a drive's
        "incomplete_draws": sum((row["laps_completed"] or 0) < row["laps_asked"] for row in rows),
        "worst_draw": {k: w.get(k) for k in ("run", "seed", "precision", "randomize", "score", "autonomy",
                                             "completion", "laps_completed", "laps_asked", "interventions")},
        "worst_seed": {"seed": results[ws]["seed"], "precision": results[ws]["precision"],
                       **{k: by_run[ws]["mean"].get(k) for k in ("score", "autonomy", "completion")}},
        "interventions": {"mean_per_run": _mean(interventions), "max_per_run": max(interventions)},
        "speed_vs_expert_pct": _mean([s.get("speed_vs_expert_pct") for s in by_run]),
    }


def run_row(result: dict[str, Any], themes: list[str]) -> dict[str, Any]:
    """One run: seed, precision, step times (wall s), best validation loss, each theme's mean and
    worst draw."""
    seconds = result.get("seconds", {})
    return {
        "name": result["name"], "seed": result["seed"], "precision": result["precision"],
        "seconds": {k: round(seconds[k], 1) for k in ("record", "train", "evaluate") if k in seconds},
        "total_seconds": result.get("total_seconds"),
        "best_val_loss": result.get("metrics", {}).get("best_val_loss"),
        "themes": {t: {"mean": result["by_theme"][t]["mean"], "worst": result["by_theme"][t]["worst"]}
                   for t in themes},
    }


def aggregate(results: list[dict[str, Any]]) -> dict[str, Any]:
    """Per theme (trained ones first, then the unseen one) :func:`theme_summary`, and per run
    :func:`run_row`. ValueError without a finished run."""
    if not results:
        raise ValueError("no finished run to aggregate")
    themes: list[str] = []
    for r in results:
        for t in [*r["trained_themes"], r["unseen_theme"]]:
            if t not in themes:
                themes.append(t)
    unseen = sorted({r["unseen_theme"] for r in results})
    return {"themes": {t: theme_summary(results, t) for t in themes}, "unseen_themes": unseen,
            "runs": [run_row(r, themes) for r in results]}


def _f(value: Any, fmt: str = "{:.1f}") -> str:
    return "-" if value is None else fmt.format(value)


def theme_table(report: dict[str, Any]) -> list[str]:
    """The per-theme markdown table (the columns are explained in docs/pilot.md)."""
    lines = ["| theme | runs x draws | score mean | autonomy % mean | laps driven | worst draw: score, autonomy "
             "(seed, precision, draw) | worst seed: mean score | interventions per run: mean / max | "
             "mean abs CTE m | speed % of expert |", "|---" * 10 + "|"]
    for theme, s in report["themes"].items():
        m, w, ws = s["mean"], s["worst_draw"], s["worst_seed"]
        label = f"{theme} (unseen)" if theme in report["unseen_themes"] else theme
        driven = (f"{s['laps_completed']}/{s['laps_asked']} ({_f(_pct(m['completion']), '{:.0f}')} %"
                  f"{', ' + str(s['incomplete_draws']) + ' draws incomplete' if s['incomplete_draws'] else ''})")
        lines.append(
            f"| {label} | {s['runs']} x {s['draws'] // max(1, s['runs'])} | {_f(m['score'])} | {_f(m['autonomy'])} | "
            f"{driven} | {_f(w['score'])}, {_f(w['autonomy'])} % (s{w['seed']}, {w['precision']}, {w['randomize']}) | "
            f"{_f(ws['score'])} (s{ws['seed']}, {ws['precision']}) | {_f(s['interventions']['mean_per_run'])} / "
            f"{s['interventions']['max_per_run']} | {_f(m['mean_abs_cte'], '{:.3f}')} | "
            f"{_f(s['speed_vs_expert_pct'], '{:.0f}')} |")
    return lines


def _pct(share: float | None) -> float | None:
    return None if share is None else 100.0 * share


def run_table(report: dict[str, Any]) -> list[str]:
    """The per-run markdown table: step times, best validation loss, each theme's mean / worst score."""
    themes = list(report["themes"])
    lines = ["| run | seed | precision | record s | train s | evaluate s | best val loss | "
             + " | ".join(f"{t}: score mean / worst" for t in themes) + " |", "|---" * (7 + len(themes)) + "|"]
    for r in report["runs"]:
        sec = r["seconds"]
        cells = [f"{_f(r['themes'][t]['mean'].get('score'))} / {_f(r['themes'][t]['worst'].get('score'))}"
                 for t in themes]
        lines.append(f"| {r['name']} | {r['seed']} | {r['precision']} | {_f(sec.get('record'), '{:.0f}')} | "
                     f"{_f(sec.get('train'), '{:.0f}')} | {_f(sec.get('evaluate'), '{:.0f}')} | "
                     f"{_f(r['best_val_loss'], '{:.5f}')} | " + " | ".join(cells) + " |")
    return lines


def link_galleries(report: dict[str, Any], out: Path) -> None:
    """Give each theme's worst draw the path (relative to ``out``) of its failure gallery, which the
    run's demo wrote (``runs/<run>/eval/gallery/<theme>-draw<N>/index.html``), where it exists."""
    from vehicle.app.eval_draws import gallery_name

    for theme, s in report["themes"].items():
        w = s["worst_draw"]
        page = Path("runs", str(w.get("run")), "eval", "gallery", gallery_name(theme, w["randomize"]), "index.html")
        w["gallery"] = page.as_posix() if (out / page).is_file() else None


def gallery_lines(report: dict[str, Any]) -> list[str]:
    """Markdown links to the worst draws' galleries (what the pilot saw before it failed)."""
    links = [f"- {theme}: [{s['worst_draw']['run']}, draw {s['worst_draw']['randomize']}]({s['worst_draw']['gallery']})"
             for theme, s in report["themes"].items() if s["worst_draw"].get("gallery")]
    return ["Failure galleries of the worst draws (frames before each intervention, with saliency):", "", *links, ""] \
        if links else []


def header_lines(report: dict[str, Any], title: str, note: str) -> list[str]:
    """robustness.md's title, command, machine, time and conditions, then ``note``, and the failed runs."""
    load = report["load_average"]
    lines = [f"# {title}", "", f"`{report['command']}`", "",
             f"CPU {report['cpu']} ({report['cores']} cores), load average {load['start'][0]:.1f} at the start and "
             f"{load['end'][0]:.1f} at the end; {report['wall_seconds']:.0f} s wall ({report['runs_done_now']} runs "
             f"done now, {report['runs_kept']} kept from before; the runs took {report['runs_seconds']:.0f} s "
             f"added up); hidden draws {report['draws']} per theme on "
             f"tracks {_ints(report['eval_tracks'])}. {note}", ""]
    if report["failed"]:
        lines += [f"FAILED runs (not in the tables): {', '.join(report['failed'])}", ""]
    return lines


def format_markdown(report: dict[str, Any]) -> str:
    """``robustness.md``: the conditions, the per-theme table and the per-run table (with ``--lanes``:
    :func:`vehicle.app.lanes_robustness.lanes_tables`)."""
    if report["recipe"] == LANES:
        from vehicle.app.lanes_robustness import lanes_tables

        lines = header_lines(report, "Robustness of the lanes demo's models", "Lane changes commanded on every "
                             "track; success = centred in the commanded lane in time and held.")
        return "\n".join([*lines, *lanes_tables(report), ""])
    lines = header_lines(report, f"Robustness of the {report['recipe']} recipe",
                         "Score = autonomy x share of the laps driven.")
    return "\n".join([*lines, *theme_table(report), "", *gallery_lines(report), *run_table(report), ""])


def machine() -> dict[str, Any]:
    """CPU model, cores and the load average now (1, 5, 15 min)."""
    from training.acceleration import cpu_caps

    return {"cpu": cpu_caps().name, "cores": os.cpu_count() or 1, "load": list(os.getloadavg())}


def run_protocol(protocol: Protocol) -> int:
    """Run (or resume) every run, then write ``robustness.json`` and ``robustness.md`` in
    ``protocol.out`` and print the tables. Returns 0, or 1 when a run failed."""
    import json

    from parts.tub.format import atomic_write

    started, at_start = time.perf_counter(), machine()
    specs, runs_dir = protocol.specs(), protocol.out / "runs"
    what = "the lanes demo" if protocol.lanes else f"the {protocol.recipe} recipe"
    say(f"robustness: {len(specs)} runs of {what} (seeds {_ints(protocol.seeds)} x "
        f"precisions {','.join(protocol.precisions)}), {protocol.jobs} at a time, in {protocol.out}")
    todo = pending_runs(specs, runs_dir)
    codes = run_all(todo, protocol, demo_command)
    results = load_results(specs, runs_dir)
    failed = [f"{s.name} (exit {codes.get(s.name)}, log {runs_dir / (s.name + '.log')})" for s in specs
              if s.name not in {r["name"] for r in results}]
    if protocol.lanes:
        from vehicle.app.lanes_robustness import aggregate_lanes as aggregate_runs
        from vehicle.app.lanes_robustness import link_lane_galleries as link
    else:
        aggregate_runs, link = aggregate, link_galleries
    try:
        report = aggregate_runs(results)
    except ValueError:
        say(f"no run finished: {'; '.join(failed)}")
        return 1
    at_end = machine()
    link(report, protocol.out)
    report.update(command=protocol.command_line(), recipe=protocol.recipe, seeds=protocol.seeds,
                  precisions=protocol.precisions, draws=protocol.draws, eval_tracks=results[0]["eval_tracks"],
                  laps=results[0]["laps"], jobs=protocol.jobs, cpu=at_start["cpu"], cores=at_start["cores"],
                  load_average={"start": at_start["load"], "end": at_end["load"]},
                  wall_seconds=round(time.perf_counter() - started, 1),
                  # each run's own wall time, added up: what the protocol cost, kept runs included
                  runs_seconds=round(sum(r.get("total_seconds") or 0.0 for r in results), 1), runs_done_now=len(todo),
                  runs_kept=len(specs) - len(todo), failed=failed)
    protocol.out.mkdir(parents=True, exist_ok=True)
    atomic_write(protocol.out / "robustness.json", json.dumps(report, indent=1) + "\n")
    markdown = format_markdown(report)
    atomic_write(protocol.out / "robustness.md", markdown)
    say(markdown)
    say(f"written: {protocol.out / 'robustness.json'}, {protocol.out / 'robustness.md'}")
    return 1 if failed else 0
