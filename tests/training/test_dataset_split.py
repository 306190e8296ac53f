"""Train/validation split by blocks or sessions (no leakage) and steering balancing."""

from __future__ import annotations

import numpy as np
import pytest

from training.balance import balance_by_steering
from training.split import split_train_val


def _runs(positions: np.ndarray) -> list[int]:
    """Lengths of runs of consecutive positions."""
    if positions.size == 0:
        return []
    cuts = np.flatnonzero(np.diff(positions) != 1) + 1
    return [len(r) for r in np.split(positions, cuts)]


def test_block_split_has_no_leakage_and_keeps_blocks_whole():
    segments = [0] * 500 + [1] * 300  # two tubs/sessions
    train, val = split_train_val(segments, 0.8, by="block", block=50, seed=3)
    assert np.intersect1d(train, val).size == 0
    assert np.array_equal(np.union1d(train, val), np.arange(800))
    assert len(val) == 150  # 0.2 x 800 = 160 -> the closest count of whole blocks of 50
    # validation = whole contiguous blocks aligned on block boundaries, never scattered frames
    assert all(n % 50 == 0 for n in _runs(val))
    assert all(p % 50 == 0 for p in val[np.r_[0, np.flatnonzero(np.diff(val) != 1) + 1]])
    # random frames would leave almost every validation frame with a training neighbour
    neighbours = np.isin(val + 1, train).sum() + np.isin(val - 1, train).sum()
    assert neighbours <= 2 * len(_runs(val))


def test_split_is_reproducible_and_seed_dependent():
    segments = [0] * 1000
    a = split_train_val(segments, 0.8, block=100, seed=1)
    b = split_train_val(segments, 0.8, block=100, seed=1)
    c = split_train_val(segments, 0.8, block=100, seed=2)
    assert np.array_equal(a[1], b[1])
    assert not np.array_equal(a[1], c[1])


def test_session_split_takes_whole_sessions():
    segments = [0] * 100 + [1] * 100 + [2] * 100 + [3] * 100 + [4] * 100
    train, val = split_train_val(segments, 0.8, by="session", seed=0)
    seg = np.asarray(segments)
    assert len(val) == 100
    assert set(seg[val]).isdisjoint(set(seg[train]))


def test_session_split_falls_back_to_blocks_with_one_session(caplog):
    train, val = split_train_val([0] * 200, 0.75, by="session", block=20)
    assert len(val) == 40 and np.intersect1d(train, val).size == 0
    assert "only one recording session" in caplog.text
    caplog.clear()
    train, val = split_train_val([0] * 190 + [1] * 10, 0.8, by="session", block=20)
    assert len(val) == 40  # one 10-record session is far from 40: blocks instead
    assert "too unequal" in caplog.text


def test_small_data_still_splits_in_blocks():
    train, val = split_train_val([0] * 30, 0.8, block=100)
    assert len(val) == 6 and len(train) == 24
    assert all(n >= 3 for n in _runs(val))  # blocks of 3 (30 // 10), not single frames


def test_split_errors_and_all_train():
    with pytest.raises(ValueError, match="TRAIN_TEST_SPLIT"):
        split_train_val([0] * 10, 1.5)
    with pytest.raises(ValueError, match="TRAIN_SPLIT_BY"):
        split_train_val([0] * 10, 0.8, by="frames")
    with pytest.raises(ValueError, match="no records"):
        split_train_val([], 0.8)
    train, val = split_train_val([0] * 10, 1.0)
    assert len(train) == 10 and len(val) == 0


def test_balance_caps_every_bin():
    rng = np.random.default_rng(0)
    angles = np.concatenate([np.zeros(900), rng.uniform(-1, 1, 100)])  # mostly straight
    kept = balance_by_steering(angles, np.arange(1000), num_bins=25, max_per_bin=40, seed=0)
    counts, _ = np.histogram(angles[kept], bins=np.histogram_bin_edges(angles, 25))
    assert counts.max() <= 40
    assert (angles[kept] == 0).sum() == 40  # the straight-ahead bin is cut to the cap
    assert (angles[kept] != 0).sum() >= 95  # curves are (nearly) all kept; only the centre bin is cut
    assert np.all(np.diff(kept) > 0)
    assert np.array_equal(kept, balance_by_steering(angles, np.arange(1000), 25, 40, seed=0))
    with pytest.raises(ValueError, match="num_bins"):
        balance_by_steering(angles, np.arange(10), num_bins=0)


def test_random_split_holds_out_single_records_reproducibly():
    """The documents' split (scikit-learn's train_test_split): random single records, by seed."""
    segments = [0] * 50 + [1] * 50
    train, val = split_train_val(segments, 0.8, by="random", seed=7)
    assert len(val) == 20 and len(train) == 80
    assert sorted(np.concatenate([train, val]).tolist()) == list(range(100))
    assert _runs(val) != [20]  # not one contiguous block
    again_train, again_val = split_train_val(segments, 0.8, by="random", seed=7)
    assert again_val.tolist() == val.tolist()
    assert split_train_val(segments, 0.8, by="random", seed=8)[1].tolist() != val.tolist()
