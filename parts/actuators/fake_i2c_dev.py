"""Run the *real* ``smbus2.SMBus`` against :class:`~parts.actuators.fake_pca9685.FakeI2C` models.

Development machines have no ``/dev/i2c-N`` (no kernel I2C support, and FUSE cannot fake the
I2C ioctls), so this patches the three system calls smbus2 makes, ``os.open``, ``os.close`` and
``fcntl.ioctl``, inside the smbus2 module only, and answers them like the kernel's i2c-dev driver:
``I2C_FUNCS``, ``I2C_SLAVE(_FORCE)`` and ``I2C_SMBUS`` transfers of the sizes the PCA9685 driver
uses (byte, byte data, I2C block data), with the ctypes structures smbus2 passes.

>>> from parts.actuators.fake_pca9685 import FakeI2C
>>> i2c = FakeI2C(); board = i2c.add_board(1, 0x40)
>>> with real_smbus2_on(i2c):
...     import smbus2
...     with smbus2.SMBus(1) as bus:
...         bus.read_byte_data(0x40, 0xFE)
30
"""

from __future__ import annotations

import errno
import itertools
import os
import re
from collections.abc import Iterator
from contextlib import contextmanager
from types import SimpleNamespace
from typing import Any

from parts.actuators.fake_pca9685 import FakeI2C, FakeSMBus

# I2C_FUNC_I2C | SMBUS_BYTE | SMBUS_BYTE_DATA | SMBUS_WORD_DATA | SMBUS_I2C_BLOCK (like bcm2835)
_FUNCS = 0x00000001 | 0x00060000 | 0x00180000 | 0x00600000 | 0x0C000000


class _OsProxy:
    """``os`` for smbus2: open/close of /dev/i2c-N go to the fake, everything else to ``os``."""

    def __init__(self, opener: Any, closer: Any) -> None:
        self.open = opener
        self.close = closer

    def __getattr__(self, name: str) -> Any:
        return getattr(os, name)


@contextmanager
def real_smbus2_on(i2c: FakeI2C) -> Iterator[None]:
    """Within the block, ``smbus2.SMBus(n)`` opens bus ``n`` of ``i2c`` through its real code."""
    import smbus2.smbus2 as impl  # noqa: PLC0415 - only when a test asks for it

    files: dict[int, SimpleNamespace] = {}
    numbers = itertools.count(10_000)

    def fake_open(path: str, flags: int, mode: int = 0o777) -> int:
        m = re.fullmatch(r"/dev/i2c-(\d+)", str(path))
        if m is None:
            return os.open(path, flags, mode)
        bus: FakeSMBus = i2c.smbus(int(m.group(1)))  # FileNotFoundError like the kernel
        fd = next(numbers)
        files[fd] = SimpleNamespace(bus=bus, address=None)
        return fd

    def fake_close(fd: int) -> None:
        if fd in files:
            files.pop(fd).bus.close()
        else:
            os.close(fd)

    def fake_ioctl(fd: int, request: int, arg: Any = 0, mutate: bool = True) -> int:
        f = files.get(fd)
        if f is None:
            raise OSError(errno.EBADF, "Bad file descriptor")
        if request == impl.I2C_FUNCS:
            arg.value = _FUNCS
        elif request in (impl.I2C_SLAVE, impl.I2C_SLAVE_FORCE):
            if not 0 <= int(arg) <= 0x7F:
                raise OSError(errno.EINVAL, "Invalid argument")
            f.address = int(arg)
        elif request == impl.I2C_SMBUS:
            _smbus_transfer(impl, f, arg)
        else:
            raise OSError(errno.ENOTTY, "Inappropriate ioctl for device")
        return 0

    saved = (impl.os, impl.ioctl)
    impl.os, impl.ioctl = _OsProxy(fake_open, fake_close), fake_ioctl
    try:
        yield
    finally:
        impl.os, impl.ioctl = saved


def _smbus_transfer(impl: Any, f: SimpleNamespace, msg: Any) -> None:
    """One I2C_SMBUS ioctl: ``msg`` is smbus2's ``i2c_smbus_ioctl_data``."""
    bus, addr = f.bus, f.address
    data = msg.data.contents
    write = msg.read_write == impl.I2C_SMBUS_WRITE
    if msg.size == impl.I2C_SMBUS_BYTE:
        if write:
            bus.write_byte(addr, msg.command)
        else:
            data.byte = bus.read_byte(addr)
    elif msg.size == impl.I2C_SMBUS_BYTE_DATA:
        if write:
            bus.write_byte_data(addr, msg.command, data.byte)
        else:
            data.byte = bus.read_byte_data(addr, msg.command)
    elif msg.size == impl.I2C_SMBUS_I2C_BLOCK_DATA:
        n = data.block[0]  # write: length; read: requested length (aliases data.byte)
        if write:
            bus.write_i2c_block_data(addr, msg.command, list(data.block[1:n + 1]))
        else:
            values = bus.read_i2c_block_data(addr, msg.command, n)
            data.block[0] = len(values)
            data.block[1:len(values) + 1] = values
    else:
        raise OSError(errno.EOPNOTSUPP, "Operation not supported by the fake adapter")
