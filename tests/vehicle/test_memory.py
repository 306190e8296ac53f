from __future__ import annotations

import pytest

from vehicle.memory import Memory


def test_list_key_stores_values_not_keys():
    mem = Memory()
    mem[["a", "b"]] = [1, 2]  # DonkeyCar stored {'a': 'a', 'b': 'b'} here
    assert mem.get(["a", "b"]) == [1, 2]
    assert mem[("a", "b")] == [1, 2]


def test_missing_key_reads_none_and_put_checks_lengths():
    mem = Memory({"x": 3})
    assert mem.get(["x", "nope"]) == [3, None]
    mem.put(["only"], (1, 2))
    assert mem["only"] == (1, 2)  # one key keeps the whole value, as in DonkeyCar
    with pytest.raises(ValueError, match=r"2 keys \['a', 'b'\] but got 3 values"):
        mem.put(["a", "b"], (1, 2, 3))
    mem.put(["a", "b"], None)
    assert mem.get(["a", "b"]) == [None, None]
