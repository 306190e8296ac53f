"""torch.distributed set-up for training on several GPUs or machines, launched with torchrun.

``torchrun --nproc_per_node N -m vehicle train ...`` (or ``manage.py train``) starts N processes
with RANK / WORLD_SIZE / LOCAL_RANK / MASTER_ADDR set; each process trains on its share of every
epoch (DistributedSampler) and DistributedDataParallel averages the gradients. Rank 0 alone writes
files and shows progress.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass

import torch
import torch.distributed as dist

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class DistInfo:
    """Where this process stands in the job (rank 0 of 1 when not distributed)."""

    rank: int = 0
    world_size: int = 1
    local_rank: int = 0

    @property
    def enabled(self) -> bool:
        return self.world_size > 1

    @property
    def is_main(self) -> bool:
        return self.rank == 0


def resolve_device(setting: str, local_rank: int = 0) -> torch.device:
    """The training device for TRAIN_DEVICE: "auto" = cuda (this process's GPU) when available, else cpu."""
    if setting == "auto":
        if torch.cuda.is_available():
            return torch.device("cuda", local_rank % torch.cuda.device_count())
        return torch.device("cpu")
    try:
        device = torch.device(setting)
    except RuntimeError as exc:
        raise ValueError(f"TRAIN_DEVICE = {setting!r} is not a device (use auto, cpu, cuda, cuda:1)") from exc
    if device.type == "cuda" and not torch.cuda.is_available():
        raise ValueError(f"TRAIN_DEVICE = {setting!r} but no CUDA GPU is available; use 'auto' or 'cpu'")
    return device


def init_distributed(device_setting: str) -> tuple[DistInfo, torch.device]:
    """Join the torchrun job when WORLD_SIZE > 1 (NCCL on GPUs, gloo on CPUs); else single process."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world <= 1:
        return DistInfo(), resolve_device(device_setting)
    rank, local_rank = int(os.environ["RANK"]), int(os.environ.get("LOCAL_RANK", "0"))
    device = resolve_device(device_setting, local_rank)
    if device.type == "cuda":
        torch.cuda.set_device(device)
    if not dist.is_initialized():
        backend = "nccl" if device.type == "cuda" else "gloo"
        dist.init_process_group(backend=backend)
        logger.info("distributed training: rank %d of %d (%s, %s)", rank, world, backend, device)
    return DistInfo(rank, world, local_rank), device


def shutdown_distributed(*, clean: bool = True) -> None:
    """Leave the process group (if joined).

    ``clean`` (every rank finished training; only rank 0's file writing came after) waits at a
    barrier first: a rank that tears gloo down while a peer is still in its last collective aborts
    the process ("terminate called without an active exception"). After an error in training the
    peers may never arrive, so there is no barrier then (torchrun stops them).
    """
    if dist.is_available() and dist.is_initialized():
        if clean:
            dist.barrier()
        dist.destroy_process_group()


def all_sum(values: list[float], info: DistInfo, device: torch.device) -> list[float]:
    """Element-wise sum of ``values`` over all processes (identity when not distributed)."""
    if not info.enabled:
        return values
    t = torch.tensor(values, dtype=torch.float64, device=device)
    dist.all_reduce(t, op=dist.ReduceOp.SUM)
    return t.tolist()
