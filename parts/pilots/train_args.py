"""The training command-line options, shared by ``manage.py train`` and ``vehicle train``.

Light on purpose (no torch): building a command parser must not load the training stack.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence


def add_train_arguments(parser: argparse.ArgumentParser) -> None:
    """The training options shared by ``manage.py train`` and ``vehicle train``."""
    parser.add_argument("--tubs", nargs="+", metavar="PATH",
                        help="tubs or folders of tubs (comma-separated also accepted); default: the car's data/")
    parser.add_argument("--model", metavar="FILE.pt", help="model file to write (default models/pilot_<date>.pt)")
    parser.add_argument("--type", dest="model_type", metavar="TYPE",
                        help="model type: linear (default), categorical, inferred, pilotnet, memory, behavior, "
                             "rnn, 3d")
    parser.add_argument("--transfer", metavar="OLD.pt", help="start from the weights of an earlier model")
    parser.add_argument("--epochs", type=int, help="most epochs (MAX_EPOCHS)")
    parser.add_argument("--batch-size", type=int, help="samples per step (BATCH_SIZE)")
    parser.add_argument("--lr", type=float, dest="learning_rate", help="Adam learning rate (LEARNING_RATE)")
    parser.add_argument("--device", help="auto, cpu, cuda, cuda:1 (TRAIN_DEVICE)")
    parser.add_argument("--workers", type=int, help="DataLoader worker processes (TRAIN_NUM_WORKERS)")
    parser.add_argument("--aug", nargs="*", metavar="NAME", dest="augmentations",
                        help="augmentations to use (AUGMENTATIONS); --aug with no name turns them off")
    parser.add_argument("--comment", help="free text stored with the model in the registry")
    parser.add_argument("--no-register", action="store_true", help="do not add the model to the registry")


def tub_list(values: Sequence[str] | None) -> list[str]:
    """``--tubs`` values as a flat list (each value may also be a comma-separated list)."""
    out: list[str] = []
    for v in values or ():
        out += [p for p in str(v).split(",") if p]
    return out
