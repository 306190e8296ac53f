"""The training plan per device (precision, layout, copies, compile), decided without the hardware."""

from __future__ import annotations

import logging

import pytest
import torch

from training.acceleration import DeviceCaps, autocast, choose_plan, grad_scaler, plan_for, to_layout

AVX512_BF16 = DeviceCaps("cpu", "AMD EPYC", native_bf16=True, can_compile=True)
OLD_CPU = DeviceCaps("cpu", "Cortex-A72", native_bf16=False, can_compile=False)


def gpu(major: int, minor: int = 0, triton: bool = True) -> DeviceCaps:
    return DeviceCaps("cuda", f"sm_{major}{minor}", native_bf16=major >= 8, compute_capability=(major, minor),
                      can_compile=triton)


def test_cpu_with_native_bf16_trains_in_bf16_channels_last():
    plan = choose_plan(AVX512_BF16)
    assert (plan.precision, plan.channels_last, plan.grad_scaler) == ("bf16", True, False)
    assert (plan.pin_memory, plan.non_blocking, plan.compile) == (False, False, False)
    assert plan.autocast_dtype is torch.bfloat16
    assert "bf16 autocast, channels_last, eager" in plan.describe()


def test_cpu_without_bf16_stays_fp32():
    plan = choose_plan(OLD_CPU)
    assert plan.precision == "fp32" and plan.autocast_dtype is None and plan.channels_last
    assert "emulated" in plan.describe()


@pytest.mark.parametrize(("caps", "precision", "scaler", "layout"), [
    (gpu(9, 0), "bf16", False, True),   # Hopper
    (gpu(8, 6), "bf16", False, True),   # Ampere consumer
    (gpu(7, 5), "fp16", True, True),    # Turing: tensor cores, no bf16
    (gpu(7, 0), "fp16", True, True),    # Volta
    (gpu(6, 1), "fp32", False, False),  # Pascal: no tensor cores
])
def test_gpu_precision_follows_compute_capability(caps, precision, scaler, layout):
    plan = choose_plan(caps)
    assert (plan.precision, plan.grad_scaler, plan.channels_last) == (precision, scaler, layout)
    assert plan.pin_memory and plan.non_blocking  # pinned host batches, asynchronous copies


def test_forcing_fp32_keeps_the_layout_and_says_so():
    plan = choose_plan(gpu(8, 0), "fp32")
    assert (plan.precision, plan.grad_scaler, plan.channels_last) == ("fp32", False, True)
    assert "TRAIN_PRECISION = 'fp32'" in plan.describe()
    assert choose_plan(AVX512_BF16, "fp32").autocast_dtype is None


def test_forcing_fp16_gets_a_grad_scaler_and_a_warning_where_slower(caplog):
    with caplog.at_level(logging.WARNING):
        plan = choose_plan(gpu(8, 0), "fp16")
    assert plan.precision == "fp16" and plan.grad_scaler
    assert "slower than bf16" in caplog.text


def test_sequence_models_keep_the_default_layout():
    assert not choose_plan(AVX512_BF16, spatial_model=False).channels_last
    assert not choose_plan(gpu(8, 0), spatial_model=False).channels_last


def test_other_devices_train_in_fp32_and_refuse_forced_half_precision():
    plan = choose_plan(DeviceCaps("mps", "Apple"))
    assert (plan.precision, plan.channels_last, plan.pin_memory) == ("fp32", False, False)
    with pytest.raises(ValueError, match="not supported on a mps device"):
        choose_plan(DeviceCaps("mps", "Apple"), "bf16")


def test_unknown_precision_is_refused_with_the_choices():
    with pytest.raises(ValueError, match="TRAIN_PRECISION = 'half': use one of auto, fp32, bf16, fp16"):
        choose_plan(AVX512_BF16, "half")


def test_compile_only_where_the_device_can(caplog):
    assert choose_plan(AVX512_BF16, compile=True).compile
    assert choose_plan(gpu(8, 0), compile=True).compile
    with caplog.at_level(logging.WARNING):
        assert not choose_plan(OLD_CPU, compile=True).compile
        assert not choose_plan(gpu(8, 0, triton=False), compile=True).compile
    assert "C++ compiler" in caplog.text and "Triton" in caplog.text
    assert not choose_plan(AVX512_BF16).compile  # never unasked


def test_this_machine_gets_a_plan_and_its_runtime_helpers_work():
    plan = plan_for(torch.device("cpu"))
    assert plan.device_type == "cpu" and plan.precision in ("bf16", "fp32")
    x = torch.zeros(2, 3, 8, 8)
    assert to_layout(x, plan).is_contiguous(memory_format=torch.channels_last)
    assert to_layout(torch.zeros(2, 3, 3, 8, 8), plan).is_contiguous()  # 5-D batches untouched
    with autocast(plan):
        y = torch.nn.functional.linear(torch.ones(1, 4), torch.ones(2, 4))
    assert y.dtype == (torch.bfloat16 if plan.precision == "bf16" else torch.float32)
    assert grad_scaler(plan) is None
    assert grad_scaler(choose_plan(AVX512_BF16, "fp16")) is not None
