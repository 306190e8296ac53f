"""``vehicle train``: train a pilot outside a car folder (or inside one with ``--car``).

    vehicle train --tubs data/tub_1 data/tub_2 --model models/mypilot.pt [--type pilotnet]
                  [--transfer models/old.pt] [--epochs 20] [--batch-size 64] [--lr 1e-3] [--aug flip shift]
    torchrun --nproc_per_node 2 -m vehicle train --tubs data --model models/ddp.pt
    vehicle train preview-aug --tubs data/tub_1 [--out aug.png] [--rows 4] [--variants 5]

Settings come from ``<car>/myconfig.py`` when there is one (``--car``, default the current
folder), else the defaults; the options override them. ``manage.py train`` takes the same options.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from vehicle.app.carconfig import add_car_options, load_for_command
from vehicle.app.interrupt import ctrl_c_stops_training
from vehicle.errors import UserError

logger = logging.getLogger(__name__)


def register(subparsers: Any) -> None:
    """Add ``vehicle train`` and ``vehicle train preview-aug``."""
    parser = subparsers.add_parser("train", help="train a pilot model from tubs",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_car_options(parser)
    add_train_arguments(parser)
    parser.set_defaults(func=_cmd_train)
    sub = parser.add_subparsers(dest="train_command", metavar="SUBCOMMAND")
    prev = sub.add_parser("preview-aug", help="write a PNG grid of augmented training frames")
    prev.add_argument("--tubs", nargs="+", metavar="PATH", help="tubs or folders of tubs (default: data/)")
    prev.add_argument("--out", default="augmentations.png", help="PNG file to write")
    prev.add_argument("--rows", type=int, default=4, help="frames (rows) to show")
    prev.add_argument("--variants", type=int, default=5, help="augmented copies per frame")
    prev.add_argument("--aug", nargs="*", metavar="NAME", dest="augmentations",
                      help="augmentations to show (default: AUGMENTATIONS)")
    prev.add_argument("--seed", type=int, default=0, help="random seed of the draws")
    add_car_options(prev, suppress=True)
    prev.set_defaults(func=_cmd_preview)


def _cmd_train(args: argparse.Namespace) -> int:
    return run_from_args(load_for_command(args), args)


def _cmd_preview(args: argparse.Namespace) -> int:
    cfg = load_for_command(args)
    out = write_preview(cfg, _tubs(args, cfg), Path(args.out), rows=args.rows, variants=args.variants,
                        augmentations=args.augmentations, seed=args.seed)
    print(f"wrote {out}")  # noqa: T201 - the command's own output
    return 0


def _tubs(args: argparse.Namespace, cfg: Any) -> list[str]:
    return tub_list(args.tubs) or [str(cfg.path("DATA_PATH"))]


def write_preview(cfg: Any, tubs: list[str], out: Path, rows: int = 4, variants: int = 5,
                  augmentations: list[str] | None = None, seed: int = 0) -> Path:
    """Write a PNG grid: ``rows`` frames spread over the tubs, each with ``variants`` augmented copies."""
    import cv2

    from parts.tub.errors import TubError
    from training.augment import Augmenter, AugmentSettings, preview_frames, preview_grid

    if rows < 1 or variants < 1:
        raise UserError("--rows and --variants must be >= 1")
    try:
        frames, angles = preview_frames(tubs, rows)
        settings = AugmentSettings.from_config(cfg, augmentations)
    except (ValueError, TubError) as exc:
        raise UserError(str(exc)) from exc
    grid = preview_grid(frames, angles, Augmenter(settings), variants, seed)
    out.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(out), cv2.cvtColor(grid, cv2.COLOR_RGB2BGR)):
        raise UserError(f"cannot write {out}; check the folder and the .png extension")
    return out


def add_train_arguments(parser: argparse.ArgumentParser) -> None:
    """The training options shared by ``manage.py train`` and ``vehicle train``: the data, the
    model file, and every hyper-parameter of :mod:`training.hyperparams` (the trainer
    console's form shows the same table and checks it with the same function)."""
    from training.hyperparams import HYPERPARAMS

    parser.add_argument("--tubs", "--tub", nargs="+", metavar="PATH",
                        help="tubs or folders of tubs (comma-separated also accepted); default: the car's data/")
    parser.add_argument("--model", metavar="FILE.pt", help="model file to write (default models/pilot_<date>.pt)")
    parser.add_argument("--transfer", metavar="OLD.pt", help="start from the weights of an earlier model")
    parser.add_argument("--comment", help="free text stored with the model in the model database")
    parser.add_argument("--recipe", metavar="NAME",
                        help="train as a source document does: track-driver-ai, udacity-bc or donkey-thesis "
                             "(sets every value the document states; the options here still win; "
                             "docs/training.md, 'Recipes')")
    parser.add_argument("--no-register", action="store_true", help="do not add the model to the model database")
    dagger = parser.add_argument_group("DAgger in the built-in simulator (docs/dagger.md)")
    dagger.add_argument("--dagger", type=int, metavar="ROUNDS",
                        help="after round 0 (--transfer, or a model trained on --tubs first), ROUNDS times: the pilot "
                             "drives the training tracks, the expert labels every frame into a new tub, the pilot is "
                             "fine-tuned on all the data and evaluated under hidden randomisation draws")
    dagger.add_argument("--dagger-records", type=int, default=2000, metavar="N", help="roll-out frames per round")
    dagger.add_argument("--dagger-beta", type=float, default=0.0, metavar="B",
                        help="probability that the expert drives a roll-out frame in round 1, halved each round "
                             "(0: the pilot drives every frame, re-centred when it leaves the road)")
    dagger.add_argument("--dagger-tracks", metavar="SEEDS", help="roll-out track seeds, e.g. 1-64 or 1,2,3 "
                                                                  "(default SIM_TRACK_SEEDS)")
    dagger.add_argument("--eval-tracks", metavar="SEEDS", help="evaluation track seeds (default SIM_EVAL_TRACK_SEEDS)")
    dagger.add_argument("--eval-draws", type=int, default=3, metavar="N", help="hidden randomisation draws per theme")
    dagger.add_argument("--eval-themes", default="road,indoor,park", metavar="NAMES",
                        help="themes evaluated (one the pilot never trained on shows transfer)")
    dagger.add_argument("--eval-laps", type=int, metavar="N", help="laps per evaluation track (default SIM_EVAL_LAPS)")
    groups: dict[str, Any] = {}
    for p in HYPERPARAMS:
        group = groups.get(p.group) or groups.setdefault(
            p.group, parser.add_argument_group(f"{p.group.lower()} (default: the car's setting)"))
        rule = p.rule()
        if p.kind == "multi" and not p.min_items:
            rule += "; the option alone for none"
        elif p.name == "model_type":
            rule += ": linear, categorical, inferred, pilotnet, memory, behavior, rnn, 3d"
        text = f"{p.help} {rule[0].upper()}{rule[1:]} ({p.setting}).".replace("%", "%%")  # argparse formats help
        if p.kind == "bool":
            group.add_argument(p.cli_flag, dest=p.name, action=argparse.BooleanOptionalAction, default=None,
                               help=text)
        elif p.kind == "multi":
            group.add_argument(p.cli_flag, dest=p.name, nargs="+" if p.min_items else "*", metavar="NAME",
                               help=text)
        else:
            # strings: parsed by hyperparams.parse, so a bad value gets the console's message
            group.add_argument(p.cli_flag, dest=p.name, metavar=p.kind.upper() if p.kind != "choice" else "NAME",
                               help=text)


def hyperparams_from_args(args: argparse.Namespace) -> dict[str, Any]:
    """The checked hyper-parameters given on the command line (absent ones keep the car's settings).

    Raises UserError naming each bad option with the rule and its reason.
    """
    from parts.pilots.models import model_type_names
    from training.hyperparams import HYPERPARAMS, parse

    given = {p.name: getattr(args, p.name) for p in HYPERPARAMS if getattr(args, p.name, None) is not None}
    clean, errors = parse(given, model_types=model_type_names())
    if errors:
        flags = {p.name: p.cli_flag for p in HYPERPARAMS}
        raise UserError("; ".join(f"{flags[n]} {_shown(given[n])}: {m}" for n, m in errors.items()))
    return clean


def _shown(value: Any) -> str:
    return " ".join(map(str, value)) if isinstance(value, list) else str(value)


def tub_list(values: Sequence[str] | None) -> list[str]:
    """``--tubs`` values as a flat list (each value may also be a comma-separated list)."""
    out: list[str] = []
    for v in values or ():
        out += [p for p in str(v).split(",") if p]
    return out


def run_from_args(cfg: Any, args: argparse.Namespace) -> int:
    """Train with the options of :func:`add_train_arguments`; prints where the results went.

    Returns the exit code (0; 130 when Ctrl-C ended it early); bad input raises
    :class:`vehicle.errors.UserError`.
    """
    from training.fit import TrainingDiverged
    from training.hyperparams import settings_for
    from training.trainer import dataset_model_path, default_model_path, train

    clean = hyperparams_from_args(args)
    model_type_name = clean.pop("model_type", None)
    recipe = _recipe(getattr(args, "recipe", None))
    try:
        if recipe is not None:
            cfg = cfg.replace(**recipe.settings)
        cfg = cfg.replace(**settings_for(clean))
    except ValueError as exc:
        raise UserError(str(exc)) from exc
    tubs = tub_list(args.tubs) or [str(cfg.path("DATA_PATH"))]
    if args.model:
        model_path = keras_name_to_pt(Path(args.model))
    elif recipe is not None and recipe.name_by_dataset:
        model_path = dataset_model_path(cfg.path("MODELS_PATH"), tubs[0])
    else:
        model_path = default_model_path(cfg.path("MODELS_PATH"))
    if recipe is not None:
        logger.info("recipe %s (%s): %s", recipe.name, recipe.document, recipe.summary)
        if recipe.drive_settings:
            logger.info("to drive as the document does, set %s", ", ".join(
                f"{k} = {v!r}" for k, v in recipe.drive_settings.items()))
    if getattr(args, "dagger", None) is not None:
        return _run_dagger(cfg, args, tubs, model_path, model_type_name, clean)
    with ctrl_c_stops_training() as interrupted:
        try:
            metrics = train(cfg, tubs, model_path, model_type_name=model_type_name, transfer=args.transfer,
                            comment=args.comment, register=not args.no_register, recipe=recipe,
                            should_stop=interrupted.is_set if interrupted else None)
        except UserError:
            raise
        except (ValueError, TrainingDiverged) as exc:
            if interrupted and interrupted.is_set() and "cancelled" in str(exc):
                print("training stopped by Ctrl-C before its first epoch ended: no model was saved",  # noqa: T201
                      file=sys.stderr)
                return 130
            raise UserError(f"training failed: {exc}") from exc
    if int(os.environ.get("RANK", "0")) == 0:
        from training.train_report import train_summary

        print(train_summary(metrics, model_path))  # noqa: T201 - the command's output
    return 130 if metrics.get("cancelled") else 0


def seed_list(text: str | None, option: str) -> list[int] | None:
    """``1-64`` or ``1,2,3`` (or a mix) as a list of ints; None for None; UserError otherwise."""
    if text is None:
        return None
    out: list[int] = []
    try:
        for part in (p.strip() for p in text.split(",") if p.strip()):
            lo, _, hi = part.partition("-")
            out += list(range(int(lo), int(hi) + 1)) if hi else [int(lo)]
    except ValueError:
        raise UserError(f"{option} {text}: give track seeds as 1-64 or 1,2,3") from None
    if not out:
        raise UserError(f"{option} {text}: give at least one track seed")
    return out


def _run_dagger(cfg: Any, args: argparse.Namespace, tubs: list[str], model_path: Path, model_type_name: str | None,
                clean: dict[str, Any]) -> int:
    """``vehicle train --dagger ROUNDS``: :func:`vehicle.app.dagger.run_dagger`; 130 after Ctrl-C."""
    from parts.sim.themes import ThemeError, theme_list
    from training.fit import TrainingDiverged
    from vehicle.app.dagger import DaggerPlan, format_rounds, run_dagger

    try:
        themes = theme_list(args.eval_themes)
    except ThemeError as exc:
        raise UserError(f"--eval-themes: {exc}") from None
    plan = DaggerPlan(rounds=args.dagger, records=args.dagger_records, beta=args.dagger_beta,
                      tracks=seed_list(args.dagger_tracks, "--dagger-tracks") or list(cfg.SIM_TRACK_SEEDS),
                      eval_tracks=seed_list(args.eval_tracks, "--eval-tracks") or list(cfg.SIM_EVAL_TRACK_SEEDS),
                      eval_draws=args.eval_draws, eval_themes=themes,
                      laps=args.eval_laps if args.eval_laps is not None else cfg.SIM_EVAL_LAPS,
                      workers=cfg.SIM_EVAL_WORKERS)
    if args.transfer and not Path(args.transfer).exists():
        raise UserError(f"--transfer {args.transfer}: no such model file (round 0 of DAgger)")
    options: dict[str, Any] = {"register": not args.no_register}
    if model_type_name is not None:
        options["model_type_name"] = model_type_name
    try:
        result = run_dagger(cfg, tubs, model_path, plan, start_model=Path(args.transfer) if args.transfer else None,
                            train_options=options, say=lambda text: print(text, flush=True))  # noqa: T201
    except KeyboardInterrupt:
        return 130
    except (ValueError, TrainingDiverged) as exc:
        raise UserError(f"DAgger: {exc}") from exc
    print("\n" + format_rounds(result["rounds"]))  # noqa: T201 - the command's own output
    print(f"last model {result['model']}; table {result['table']}")  # noqa: T201
    return 0


KERAS_SUFFIXES = (".h5", ".keras", ".tflite", ".hdf5")


def keras_name_to_pt(path: Path) -> Path:
    """DonkeyCar's ``--model models/x.h5``: a PyTorch model is written to ``models/x.pt`` instead,
    with a one-line note (this project never writes Keras files)."""
    if path.suffix.lower() not in KERAS_SUFFIXES:
        return path
    pt = path.with_suffix(".pt")
    logger.warning("--model %s: %s is a Keras file name; writing the PyTorch model to %s (drive with "
                   "--model %s)", path, path.suffix, pt, pt)
    return pt


def _recipe(name: str | None) -> Any:
    """The recipe called ``name`` (None for None); UserError naming the known ones otherwise."""
    if name is None:
        return None
    from training.recipes import recipe

    try:
        return recipe(name)
    except ValueError as exc:
        raise UserError(f"--recipe: {exc}") from exc


def train_car(cfg: Any, args: argparse.Namespace) -> int:
    """``manage.py train``: train a model on the car's tubs (default ``data/``) and write it to
    ``--model`` (default ``models/pilot_<date>_<n>.pt``), with the loss curve, the metrics JSON and
    an entry in the car's model database. Returns the exit code.

    Paths are the car's, wherever manage.py is run from: a relative ``--model`` is written in the
    car folder (so the model and its database entry land where ``vehicle models`` looks); relative
    ``--tubs`` and ``--transfer`` are read from the car folder, or from the current folder when
    only it has them.
    """
    car = Path(cfg.CAR_PATH)

    def read_path(value: str) -> str:
        path = Path(value).expanduser()
        if not path.is_absolute() and ((car / path).exists() or not path.exists()):
            path = car / path
        return str(path)

    args.tubs = [read_path(tub) for tub in tub_list(getattr(args, "tubs", None))] or None
    if getattr(args, "transfer", None):
        args.transfer = read_path(args.transfer)
    if getattr(args, "model", None):
        args.model = str(car / Path(args.model).expanduser())  # an absolute path stays as it is
    return run_from_args(cfg, args)
