"""Distributed training: torchrun with 2 CPU processes (gloo) on a tiny tub."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from parts.pilots.modelfile import load_model

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_torchrun_two_processes_gloo(tiny_tub, tmp_path):
    model = tmp_path / "ddp.pt"
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
    cmd = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node", "2",
           "-m", "vehicle", "train", "--car", str(tmp_path), "--tubs", str(tiny_tub), "--model", str(model),
           "--epochs", "1", "--batch-size", "16", "--device", "cpu", "--aug", "--no-register"]
    done = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=240)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "rank 1 of 2 (gloo, cpu)" in done.stderr
    assert done.stdout.count("saved ") == 1  # rank 0 alone writes and reports
    _, meta = load_model(model)
    assert meta["training"]["world_size"] == 2
    metrics = json.loads((tmp_path / "ddp.metrics.json").read_text())
    # each process trained on its half: 96 training samples per epoch in total, not 2 x 96
    assert metrics["epoch_samples"] == [96]
    assert metrics["val_samples"] == 24 and len(metrics["val_loss"]) == 1
