"""GPIO through gpiozero, shared by the drivetrains' pins and the GPIO wheel encoders: the bench
mode (GPIO_MOCK: gpiozero's MockFactory with PWM-capable pins) and one place that turns "this
machine has no GPIO" into one line. gpiozero is imported only when a part opens its pins."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

#: what to do on a machine without GPIO (said by every part that needs GPIO pins)
NO_GPIO_FIX = ("run on a Raspberry Pi with a GPIO backend (`sudo apt install python3-lgpio`, a venv made with "
               "--system-site-packages), or set GPIO_MOCK = True in myconfig.py to run the car on simulated pins")


def mock_factory() -> Any:
    """GPIO_MOCK's pin factory: gpiozero's MockFactory whose pins do PWM (MockPWMPin), so servos,
    PWM motor pins and encoders all open; nothing is driven and inputs stay idle."""
    from gpiozero.pins.mock import MockFactory, MockPWMPin  # noqa: PLC0415 - on open only

    return MockFactory(pin_class=MockPWMPin)


def pin_factory(mock: bool) -> Any:
    """The pin factory for a car's GPIO parts: :func:`mock_factory` with GPIO_MOCK, else None
    (gpiozero's own choice of backend)."""
    return mock_factory() if mock else None


@contextmanager
def gpio_errors(where: str, error: Callable[[str], Exception]) -> Iterator[None]:
    """Make gpiozero devices inside: no ``PinFactoryFallback`` warning per backend gpiozero tries,
    and a missing gpiozero or a machine without GPIO becomes one ``error(message)`` starting with
    ``where`` that says how to fix it. Other gpiozero errors pass through."""
    try:
        from gpiozero.exc import BadPinFactory, PinFactoryFallback  # noqa: PLC0415 - on open only
    except ImportError as exc:
        raise error(f"{where} needs gpiozero: pip install 'vehicle-rc[car]'") from exc
    try:
        with warnings.catch_warnings():
            # gpiozero warns once per backend it cannot load before it gives up: the one line below says it all
            warnings.simplefilter("ignore", PinFactoryFallback)
            yield
    except BadPinFactory as exc:
        raise error(f"{where}: no GPIO here ({exc}); {NO_GPIO_FIX}") from exc
