"""The named memory that parts share: a dict of memory keys (see vehicle.keys) to values."""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from typing import Any


class Memory:
    """DonkeyCar-compatible shared memory.

    ``mem["a"]``, ``mem["a"] = 1``, ``mem[["a", "b"]] = (1, 2)``, ``mem.put(keys, values)`` and
    ``mem.get(keys)`` behave as in DonkeyCar (a missing key reads None), without its list-key bug.
    """

    def __init__(self, values: dict[str, Any] | None = None) -> None:
        self.d: dict[str, Any] = dict(values or {})

    def __setitem__(self, key: str | Sequence[str], value: Any) -> None:
        if isinstance(key, str):
            self.d[key] = value
        else:
            self.put(list(key), value)

    def __getitem__(self, key: str | Sequence[str]) -> Any:
        if isinstance(key, str):
            return self.d[key]
        return [self.d.get(k) for k in key]

    def __contains__(self, key: object) -> bool:
        return key in self.d

    def __iter__(self) -> Iterator[str]:
        return iter(self.d)

    def __len__(self) -> int:
        return len(self.d)

    def update(self, values: dict[str, Any]) -> None:
        """Set several keys at once."""
        self.d.update(values)

    def put(self, keys: Sequence[str], values: Any) -> None:
        """Store one value per key; with one key the whole value is stored.

        Raises:
            ValueError: more than one key and ``values`` is not a sequence of the same length.
        """
        if len(keys) == 1:
            self.d[keys[0]] = values
            return
        if values is None:
            for k in keys:
                self.d[k] = None
            return
        if not isinstance(values, list | tuple) or len(values) != len(keys):
            got = len(values) if isinstance(values, list | tuple) else type(values).__name__
            raise ValueError(f"{len(keys)} keys {list(keys)} but got {got} values")
        for k, v in zip(keys, values, strict=True):
            self.d[k] = v

    def get(self, keys: Iterable[str]) -> list[Any]:
        """The values of ``keys`` in order, None for keys never set."""
        return [self.d.get(k) for k in keys]

    def keys(self) -> Iterable[str]:
        """All keys set so far."""
        return self.d.keys()

    def values(self) -> Iterable[Any]:
        """All values."""
        return self.d.values()

    def items(self) -> Iterable[tuple[str, Any]]:
        """All (key, value) pairs."""
        return self.d.items()
