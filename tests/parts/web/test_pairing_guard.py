"""Issue 27 item 14: wrong pairing tokens are slowed per client and logged throttled; a weak
WEB_TOKEN is refused with a one-line error that says how weak it is."""

from __future__ import annotations

import logging

import pytest

from parts.web import pairing


class Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def test_failures_lock_one_client_out_for_a_growing_time(caplog):
    caplog.set_level(logging.INFO)
    clock = Clock()
    guard = pairing.FailureGuard("console", clock=clock)
    for _ in range(pairing.FREE_FAILURES):
        assert guard.wait_s("1.2.3.4") == 0
        guard.failed("1.2.3.4")
    first = guard.wait_s("1.2.3.4")
    assert first >= 1
    assert guard.wait_s("5.6.7.8") == 0  # another client is not locked out
    clock.now += first
    assert guard.wait_s("1.2.3.4") == 0
    guard.failed("1.2.3.4")
    assert guard.wait_s("1.2.3.4") > first  # the wait doubles
    for _ in range(50):  # a burst (a real server refuses these unchecked: they only lengthen the wait here)
        clock.now += 0.5
        guard.failed("1.2.3.4")
    assert guard.wait_s("1.2.3.4") <= pairing.MAX_LOCKOUT_S
    lines = [r.getMessage() for r in caplog.records]
    assert 1 <= len(lines) <= 5 and "1.2.3.4" in lines[0] and "wrong pairing token" in lines[0]
    guard.succeeded("1.2.3.4")
    assert guard.wait_s("1.2.3.4") == 0


def test_the_guard_remembers_a_bounded_number_of_clients():
    guard = pairing.FailureGuard("console", clock=Clock())
    for i in range(pairing.MAX_CLIENTS * 3):
        guard.failed(f"10.0.{i // 256}.{i % 256}")
    assert len(guard) <= pairing.MAX_CLIENTS


@pytest.mark.parametrize("token, weak", [("12345678", True), ("abcdefghij", True), ("aaaaaaaaaaaaaaaaaaaa", True),
                                         ("pairing-token-42", False), ("correct-horse-battery", False),
                                         ("Ab3$efGh9!kQ", False)])
def test_token_strength(token, weak):
    problem = pairing.token_weakness(token)
    assert (problem is not None) == weak
    if weak:
        assert "bits" in problem


def test_a_weak_token_is_refused_saying_how_weak():
    with pytest.raises(ValueError, match=r"WEB_TOKEN .*too weak.*27 bits"):
        pairing.resolve_token("0.0.0.0", "12345678")
