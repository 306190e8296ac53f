"""How fast this machine trains a model, measured in a second or two: samples per second of the
training step (forward, loss, backward, Adam) at a given input, batch size and precision plan.

What the demo's start-up line multiplies by its planned sample-steps (vehicle/app/demo_estimate.py):
a rate measured on the host, as it is loaded now, says more than the CPU's kind.
"""

from __future__ import annotations

import logging
import time
from typing import Any

import torch

from training.acceleration import apply_layout, autocast, plan_for, to_layout

logger = logging.getLogger(__name__)


def measure_step_rate(model_type: str, input_shape: tuple[int, int, int], batch_size: int, *,
                      precision: str = "auto", seconds: float = 1.5, warmup_steps: int = 2,
                      max_steps: int = 200, options: dict[str, Any] | None = None) -> float:
    """Training samples per second of ``model_type`` on random ``input_shape`` (C, H, W) batches on
    the CPU, in the plan training would choose for ``precision`` (TRAIN_PRECISION), with torch's
    current thread count. Runs ``warmup_steps`` unmeasured (oneDNN picks its kernels on the first),
    then steps until ``seconds`` have passed (at least 2 steps, at most ``max_steps``). ``options``:
    the model's (MODEL_OPTIONS). The data path (augmentations, loading) is not included."""
    from parts.pilots.models import create_model
    from training.fit import FitSettings, make_optimizer

    device = torch.device("cpu")
    model = create_model(model_type, input_shape, **(options or {}))
    plan = plan_for(device, precision, spatial_model=model.frames == 1 and model.views == 1)
    apply_layout(model, plan)
    model.train()
    optimizer = make_optimizer(model, FitSettings(), device)
    generator = torch.Generator().manual_seed(0)
    x = to_layout(torch.rand((batch_size, *input_shape), generator=generator) * 2 - 1, plan)
    extra = torch.zeros((batch_size, model.extra_size)) if model.extra_size else None
    with torch.no_grad(), autocast(plan):
        out_shape = model(x, extra).shape
    y = torch.rand(tuple(out_shape), generator=generator) * 2 - 1

    def step() -> None:
        with autocast(plan):
            out = model(x, extra)
        loss = model.loss(out.float(), y)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()

    for _ in range(warmup_steps):
        step()
    steps, start = 0, time.perf_counter()
    while steps < 2 or (time.perf_counter() - start < seconds and steps < max_steps):
        step()
        steps += 1
    rate = steps * batch_size / (time.perf_counter() - start)
    logger.info("training step of %s at %s, batch %d (%s): %.0f samples/s", model_type, input_shape, batch_size,
                plan.describe(), rate)
    return rate
