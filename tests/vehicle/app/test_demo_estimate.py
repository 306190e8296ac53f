"""The demo's expected time: measured rates of this host times the work the demo plans."""

from __future__ import annotations

import pytest

from vehicle.app import demo_estimate as de
from vehicle.app.demo_estimate import DemoWork, HostRates, estimate_seconds, expectation_line, plan_work


def test_plan_work_counts_sample_steps_validation_and_laps():
    work = plan_work(12000, 10, 0.8, eval_tracks=5, laps=2, themes=3)
    assert work == DemoWork(records=12000, sample_steps=96000, val_samples=24000, eval_laps=60)
    # a fixed number of batches per epoch replaces the pass over the training records
    assert plan_work(12000, 3, 0.8, 5, 2, 3, steps_per_epoch=100, batch_size=64).sample_steps == 3 * 6400


def test_estimate_is_the_work_at_the_measured_rates(monkeypatch):
    monkeypatch.setattr(de, "TRAIN_LOOP_SHARE", 0.5)
    monkeypatch.setattr(de, "RECORDS_PER_EVAL_LAP", 100.0)
    monkeypatch.setattr(de, "VAL_COST", 0.25)
    work = DemoWork(records=1000, sample_steps=4000, val_samples=2000, eval_laps=6)
    est = estimate_seconds(work, HostRates(train_samples_per_s=100.0, records_per_s=200.0))
    assert est["record"] == pytest.approx(5.0)  # 1000 records at 200/s
    assert est["train"] == pytest.approx((4000 + 0.25 * 2000) / 50.0)  # 90 s at half the bare step's rate
    assert est["evaluate"] == pytest.approx(6 * 100 / 200.0)
    assert est["total"] == pytest.approx(5.0 + 90.0 + 3.0)
    # a host twice as fast (or half as loaded) expects half the time
    fast = estimate_seconds(work, HostRates(200.0, 400.0))
    assert fast["total"] == pytest.approx(est["total"] / 2)
    with pytest.raises(ValueError, match="positive"):
        estimate_seconds(work, HostRates(0.0, 1.0))


def test_expectation_line_names_total_parts_and_what_was_measured():
    rates = HostRates(train_samples_per_s=330.0, records_per_s=400.0)
    line = expectation_line({"record": 30.0, "train": 95.0, "evaluate": 20.0, "total": 145.0}, rates,
                            "AMD EPYC 7B12", "fp32", 2)
    assert line.startswith("expected time on this machine as loaded now: about 2.5 min (record ~30 s, train ~95 s, "
                           "evaluate ~20 s)")
    assert "330 training samples/s (fp32, 2 torch threads) and 400 records/s on AMD EPYC 7B12" in line
    assert "about 12 min" in expectation_line({"record": 1.0, "train": 700.0, "evaluate": 1.0, "total": 702.0},
                                              rates, "cpu", "bf16", 1)


def test_demo_expectation_uses_the_demo_settings_and_arguments():
    rates = HostRates(train_samples_per_s=1000.0, records_per_s=1000.0)
    line = de.demo_expectation(12000, 10, 5, 2, 1, rates=rates)
    work = plan_work(12000, 10, 0.8, 5, 2, 3)
    total = estimate_seconds(work, rates)["total"]
    assert f"about {de._seconds(total)} (" in line and "1 torch thread)" in line
    assert de.demo_expectation(6000, 10, 5, 2, 1, rates=rates) != line  # fewer records, less time


def test_measured_step_rate_is_a_positive_rate_of_a_real_training_step(torch_one_thread):
    from training.calibrate import measure_step_rate

    rate = measure_step_rate("linear", (3, 64, 64), batch_size=4, precision="fp32", seconds=0.01, max_steps=3)
    assert 0 < rate < 1e6


def test_demo_expectation_measures_at_the_precision_the_demo_will_use(monkeypatch):
    # before: the host was measured at TRAIN_PRECISION "auto" whatever --precision said
    asked = []

    def measure(cfg, *args, **kwargs):
        asked.append(cfg.TRAIN_PRECISION)
        return HostRates(train_samples_per_s=1000.0, records_per_s=1000.0)

    monkeypatch.setattr(de, "measure_host", measure)
    line = de.demo_expectation(12000, 10, 5, 2, 1, precision="fp32")
    assert asked == ["fp32"] and "(fp32, 1 torch thread)" in line
