"""FastDropout: torch's dropout semantics with a cheaper CPU mask."""

from __future__ import annotations

import pytest
import torch

from parts.pilots.models.base import FastDropout


@pytest.mark.parametrize("p", [0.2, 0.5])
def test_drops_the_asked_share_and_keeps_the_expectation(p):
    torch.manual_seed(0)
    x = torch.ones(400_000)
    y = FastDropout(p).train()(x)
    dropped = float((y == 0).double().mean())
    assert abs(dropped - p) < 0.004  # 400k draws: the standard error is below 0.001
    kept = y[y != 0]
    assert torch.allclose(kept, torch.full_like(kept, 65536 / round((1 - p) * 65536)))
    assert abs(float(y.double().mean()) - 1.0) < 0.01  # unbiased: E[y] = x


def test_gradient_flows_through_the_kept_elements_only():
    torch.manual_seed(1)
    x = torch.randn(64, 24, 9, 9, requires_grad=True)
    y = FastDropout(0.3).train()(x)
    y.sum().backward()
    kept = y.detach() != 0
    scale = 65536 / round(0.7 * 65536)
    assert torch.equal(x.grad != 0, kept)
    assert torch.allclose(x.grad[kept], torch.full_like(x.grad[kept], scale))
    assert torch.allclose(y[kept], x.detach()[kept] * scale)


def test_same_seed_same_mask_and_layout_kept():
    x = torch.randn(8, 24, 10, 12).contiguous(memory_format=torch.channels_last)
    torch.manual_seed(3)
    a = FastDropout(0.2).train()(x)
    torch.manual_seed(3)
    b = FastDropout(0.2).train()(x)
    assert torch.equal(a, b)
    assert a.is_contiguous(memory_format=torch.channels_last)
    y = FastDropout(0.2).train()(x.transpose(1, 3))  # not dense in any order: made contiguous first
    assert y.shape == x.transpose(1, 3).shape


def test_eval_mode_and_edge_rates_are_torch_dropout():
    x = torch.randn(1000)
    assert torch.equal(FastDropout(0.2).eval()(x), x)
    assert torch.equal(FastDropout(0.0).train()(x), x)
    assert torch.equal(FastDropout(1.0).train()(x), torch.zeros_like(x))
    assert isinstance(FastDropout(0.2), torch.nn.Dropout)  # a drop-in: repr, state dict, export


def test_bf16_inputs_stay_bf16():
    torch.manual_seed(0)
    y = FastDropout(0.2).train()(torch.ones(10_000, dtype=torch.bfloat16))
    assert y.dtype is torch.bfloat16
    assert abs(float((y == 0).float().mean()) - 0.2) < 0.02
