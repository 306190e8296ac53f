"""What makes a setting's value valid: a range next to each setting, and rules across settings.

A setting of config_defaults.py declares its range in its annotation::

    DRIVE_LOOP_HZ: Annotated[int, Range(1, 1000, unit="Hz")] = 20
    WEB_TOKEN: Annotated[str | None, Length(min=8, secret=True)] = None

Settings that are only valid together (a PWM pulse width depends on the PWM frequency; the servo
and the ESC need their own channels; the actuator watchdog must outlast a loop) are checked by
the functions in :data:`RULES`. The loader (:mod:`vehicle.config`) runs both after the user's
overrides and reports the first problem as one line that names the file, the line, the setting
and what is valid. Nothing here imports anything beyond the standard library.
"""

from __future__ import annotations

import math
import string
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any

#: pulse widths servos and ESCs can be sent, µs (the RC standard is 1000-2000; some servos need
#: a little more travel). `vehicle calibrate` refuses anything outside, so does the config.
PULSE_MIN_US = 500.0
PULSE_MAX_US = 2500.0
#: the PCA9685's 12-bit counter: a pulse is 0-4095 ticks of 1/4096 period
MAX_TICK = 4095
#: PRE_SCALE register limits (datasheet 7.3.5): 3..255
PRESCALE_MIN, PRESCALE_MAX = 3, 255
#: what a pulse setting must be (the rule :func:`_pwm_pulses` checks it against PWM_FREQ)
PULSE_VALID = ("a pulse of 500 to 2500 µs at PWM_FREQ (123 to 612 ticks at 60 Hz), found with "
               "`vehicle calibrate`")
#: what None means for ACTUATOR_WATCHDOG_S
WATCHDOG_OFF = "None switches it off (not recommended: a stalled loop then keeps the last throttle)"
#: the pulse settings, each in ticks at PWM_FREQ
PULSE_SETTINGS = ("STEERING_LEFT_PWM", "STEERING_RIGHT_PWM", "THROTTLE_FORWARD_PWM",
                  "THROTTLE_STOPPED_PWM", "THROTTLE_REVERSE_PWM")


def number_text(x: float) -> str:
    """A number as a person writes it: 1000, 0.5, 25000000 (no exponent for whole numbers)."""
    if isinstance(x, float) and x.is_integer() and abs(x) < 1e16:
        return str(int(x))
    return f"{x:g}" if isinstance(x, float) else str(x)


def _is_number(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def _numbers(value: Any) -> list[Any]:
    """The numbers in a value: itself, or those of a list, tuple or dict, however nested."""
    if _is_number(value):
        return [value]
    if isinstance(value, dict):
        value = list(value.values())
    if isinstance(value, list | tuple):
        return [x for item in value for x in _numbers(item)]
    return []


@dataclass(frozen=True)
class Range:
    """Numbers from ``lo`` to ``hi`` (None: unbounded); ``lo_open``/``hi_open`` exclude the bound.

    A list, tuple or dict value is checked number by number (nested ones too). ``None`` passes
    (the type says whether it is allowed); ``note`` is added to the description (e.g. what None
    means).
    """

    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    unit: str = ""
    note: str = ""

    def problem(self, value: Any) -> str | None:
        """Why ``value`` is invalid, or None."""
        items = _numbers(value)
        for item in items:
            why = self._item_problem(item)
            if why:
                return why if items == [value] else f"holds {number_text(item)}, which {why}"
        return None

    def _item_problem(self, x: float) -> str | None:
        if not math.isfinite(x):
            return "is not a finite number"
        below = self.lo is not None and (x <= self.lo if self.lo_open else x < self.lo)
        above = self.hi is not None and (x >= self.hi if self.hi_open else x > self.hi)
        return "is out of range" if below or above else None

    def describe(self) -> str:
        """What is valid, e.g. ``1 to 1000 Hz`` or ``above 0 and at most 1 s``."""
        unit = f" {self.unit}" if self.unit else ""
        lo, hi = self.lo, self.hi
        if lo is not None and hi is not None and not (self.lo_open or self.hi_open):
            text = f"{number_text(lo)} to {number_text(hi)}{unit}"
        else:
            parts = []
            if lo is not None:
                parts.append(f"{'above' if self.lo_open else 'at least'} {number_text(lo)}")
            if hi is not None:
                parts.append(f"{'below' if self.hi_open else 'at most'} {number_text(hi)}")
            text = (" and ".join(parts) or "any finite number") + unit
        return f"{text}; {self.note}" if self.note else text

    def show(self, name: str, value: Any) -> str:
        """How the value appears in a message."""
        return f"{name} = {value!r}"


def secret_bits(text: str) -> float:
    """A rough guess of a secret's strength in bits: its length (at most twice its distinct
    characters, so ``aaaa...`` counts little) times log2 of the alphabets it draws from (digits,
    lower case, upper case, anything else)."""
    pools = ((string.digits, 10), (string.ascii_lowercase, 26), (string.ascii_uppercase, 26))
    size = sum(n for chars, n in pools if any(c in chars for c in text))
    if any(not any(c in chars for chars, _n in pools) for c in text):
        size += 32
    length = min(len(text), 2 * len(set(text)))
    return length * math.log2(size) if size else 0.0


@dataclass(frozen=True)
class Length:
    """A string or list of ``min`` to ``max`` items; ``secret`` values are never printed and, with
    ``min_bits``, must be that hard to guess (:func:`secret_bits`)."""

    min: int | None = None
    max: int | None = None
    secret: bool = False
    note: str = ""
    min_bits: int | None = None

    def problem(self, value: Any) -> str | None:
        """Why ``value`` is invalid, or None."""
        if value is None or not hasattr(value, "__len__"):
            return None
        n = len(value)
        if self.min is not None and n < self.min:
            return "is empty" if n == 0 else "is too short"
        if self.max is not None and n > self.max:
            return "is too long"
        if self.min_bits is not None and isinstance(value, str) and (bits := secret_bits(value)) < self.min_bits:
            return f"is too weak (about {bits:.0f} bits of guessing)"
        return None

    def describe(self) -> str:
        """What is valid, e.g. ``at least 8 characters``."""
        what = "characters" if self.secret else "items"
        if self.min is not None and self.max is not None:
            text = f"{self.min} to {self.max} {what}"
        elif self.min is not None:
            text = f"at least {self.min} {what}" if not (self.min == 1 and what == "items") \
                else "at least one item"
        else:
            text = f"at most {self.max} {what}"
        if self.min_bits is not None:
            text += (f" and about {self.min_bits} bits (e.g. 16 random letters and digits; repeated characters "
                     "and a single kind of character count little)")
        return f"{text}; {self.note}" if self.note else text

    def show(self, name: str, value: Any) -> str:
        """How the value appears in a message (a secret shows only its length)."""
        if self.secret and isinstance(value, str):
            return f"{name} ({len(value)} characters)"
        return f"{name} = {value!r}"


@dataclass(frozen=True)
class Checked:
    """A setting whose valid values depend on other settings: a rule of :data:`RULES` checks it;
    ``valid`` says what for the reference."""

    valid: str

    def problem(self, value: Any) -> str | None:
        """Never a problem on its own (the rule decides)."""
        return None

    def describe(self) -> str:
        """What is valid."""
        return self.valid

    def show(self, name: str, value: Any) -> str:
        """How the value appears in a message."""
        return f"{name} = {value!r}"


Constraint = Range | Length | Checked


@dataclass(frozen=True)
class Problem:
    """A rule's finding: the setting it is about, the whole message, and the other settings
    involved (the loader points at the line of whichever of them the user set)."""

    setting: str
    message: str
    related: tuple[str, ...] = ()


Rule = Callable[[Mapping[str, Any]], Iterator[Problem]]


def pwm_timing(freq_hz: float, osc_hz: float) -> tuple[int, float, float]:
    """``(prescale, real frequency in Hz, µs per tick)`` of a PCA9685 asked for ``freq_hz``
    (rounded like both Adafruit libraries: 60 Hz -> prescale 101, 59.84 Hz, 4.08 µs)."""
    prescale = int(osc_hz / (4096.0 * freq_hz) + 0.5) - 1
    real = osc_hz / 4096.0 / (prescale + 1)
    return prescale, real, 1e6 / real / 4096.0


def pulse_tick_range(tick_us: float) -> tuple[int, int]:
    """The ticks that make a pulse of PULSE_MIN_US to PULSE_MAX_US at ``tick_us`` µs per tick."""
    return math.ceil(PULSE_MIN_US / tick_us), min(MAX_TICK, math.floor(PULSE_MAX_US / tick_us))


def _pwm_pulses(v: Mapping[str, Any]) -> Iterator[Problem]:
    freq, osc = v["PWM_FREQ"], v["PCA9685_OSC_HZ"]
    prescale, real, tick_us = pwm_timing(freq, osc)
    if not PRESCALE_MIN <= prescale <= PRESCALE_MAX:
        low = osc / 4096.0 / (PRESCALE_MAX + 1)
        high = osc / 4096.0 / (PRESCALE_MIN + 1)
        yield Problem("PWM_FREQ", f"PWM_FREQ = {number_text(freq)} is outside what the PCA9685 can "
                      f"make with PCA9685_OSC_HZ = {number_text(osc)}; valid: {math.ceil(low)} to "
                      f"{math.floor(high)} Hz (servos and ESCs: 50 to 60)", ("PCA9685_OSC_HZ",))
        return
    lo, hi = pulse_tick_range(tick_us)
    valid = (f"{lo} to {hi} ticks ({number_text(PULSE_MIN_US)} to {number_text(PULSE_MAX_US)} µs, "
             "what servos and ESCs take; find yours with `vehicle calibrate`)")
    if lo > hi:
        yield Problem("PWM_FREQ", f"PWM_FREQ = {number_text(freq)} makes a period of {1e6 / real:.0f} µs, "
                      f"too short for servo pulses of {number_text(PULSE_MIN_US)} µs and more; "
                      "valid: 50 to 60 Hz for servos and ESCs", ("PCA9685_OSC_HZ",))
        return
    for name in PULSE_SETTINGS:
        ticks = v[name]
        if not lo <= ticks <= hi:
            yield Problem(name, f"{name} = {ticks} is a {ticks * tick_us:.0f} µs pulse at PWM_FREQ = "
                          f"{number_text(freq)} ({real:.2f} Hz); valid: {valid}",
                          ("PWM_FREQ", "PCA9685_OSC_HZ"))
            return
    left, right = v["STEERING_LEFT_PWM"], v["STEERING_RIGHT_PWM"]
    if left == right:
        yield Problem("STEERING_LEFT_PWM", f"STEERING_LEFT_PWM and STEERING_RIGHT_PWM are both {left}: "
                      "the wheels could not turn; valid: two pulses that differ (full left and full "
                      "right, found with `vehicle calibrate`)", ("STEERING_RIGHT_PWM",))
    fwd, stop, rev = v["THROTTLE_FORWARD_PWM"], v["THROTTLE_STOPPED_PWM"], v["THROTTLE_REVERSE_PWM"]
    if not (rev < stop < fwd or rev > stop > fwd):
        yield Problem("THROTTLE_STOPPED_PWM", f"THROTTLE_STOPPED_PWM = {stop} must be the ESC's neutral; "
                      f"valid: a pulse strictly between THROTTLE_REVERSE_PWM ({rev}) and "
                      f"THROTTLE_FORWARD_PWM ({fwd}) (recalibrate with `vehicle calibrate`)",
                      ("THROTTLE_FORWARD_PWM", "THROTTLE_REVERSE_PWM"))


def _channels(v: Mapping[str, Any]) -> Iterator[Problem]:
    if v["STEERING_CHANNEL"] == v["THROTTLE_CHANNEL"]:
        yield Problem("THROTTLE_CHANNEL", f"STEERING_CHANNEL and THROTTLE_CHANNEL are both "
                      f"{v['THROTTLE_CHANNEL']}; valid: two different channels 0 to 15 (the servo and "
                      "the ESC each need their own)", ("STEERING_CHANNEL",))


def _watchdog(v: Mapping[str, Any]) -> Iterator[Problem]:
    watchdog, hz = v["ACTUATOR_WATCHDOG_S"], v["DRIVE_LOOP_HZ"]
    if watchdog is not None and watchdog < 2.0 / hz:
        yield Problem("ACTUATOR_WATCHDOG_S", f"ACTUATOR_WATCHDOG_S = {watchdog!r} is shorter than two "
                      f"loops at DRIVE_LOOP_HZ = {hz} ({number_text(2.0 / hz)} s): the drivetrain "
                      f"would go to neutral between commands; valid: {number_text(2.0 / hz)} to 1 s "
                      "(or a faster loop)", ("DRIVE_LOOP_HZ",))


def _tub_schema(v: Mapping[str, Any]) -> Iterator[Problem]:
    inputs, types = v["TUB_INPUTS"], v["TUB_TYPES"]
    if len(inputs) != len(types):
        yield Problem("TUB_TYPES", f"TUB_TYPES = {types!r} has {len(types)} types for {len(inputs)} "
                      "TUB_INPUTS; valid: one type per TUB_INPUTS key, in the same order",
                      ("TUB_INPUTS",))


def _behaviors(v: Mapping[str, Any]) -> Iterator[Problem]:
    n, initial = len(v["BEHAVIOR_LIST"]), v["BEHAVIOR_INITIAL"]
    if n and not 0 <= initial < n:
        yield Problem("BEHAVIOR_INITIAL", f"BEHAVIOR_INITIAL = {initial} is not an index of "
                      f"BEHAVIOR_LIST ({n} behaviours); valid: 0 to {n - 1}", ("BEHAVIOR_LIST",))


def _track(v: Mapping[str, Any]) -> Iterator[Problem]:
    radius, width, size = v["SIM_TRACK_MIN_RADIUS"], v["SIM_ROAD_WIDTH"], v["SIM_TRACK_SIZE"]
    low, high = width / 2 + 0.05, size / 2
    if not low <= radius <= high:
        yield Problem("SIM_TRACK_MIN_RADIUS", f"SIM_TRACK_MIN_RADIUS = {radius!r} m does not fit a road "
                      f"of SIM_ROAD_WIDTH = {width!r} m on a track of SIM_TRACK_SIZE = {size!r} m; "
                      f"valid: {low:.2f} to {high:.2f} m (half the road width + 5 cm, up to half "
                      "the track size)", ("SIM_ROAD_WIDTH", "SIM_TRACK_SIZE"))


def _ordered_pair(name: str) -> Rule:
    def rule(v: Mapping[str, Any]) -> Iterator[Problem]:
        lo, hi = v[name]
        if lo > hi:
            yield Problem(name, f"{name} = {v[name]!r} is (high, low); valid: (low, high) with "
                          "low <= high")
    return rule


#: rules across settings, run in order after every setting passed its own range
RULES: tuple[Rule, ...] = (_pwm_pulses, _channels, _watchdog, _tub_schema, _behaviors, _track,
                           _ordered_pair("AUG_BLUR_RANGE"), _ordered_pair("SIM_EVAL_LANE_CHANGE_EVERY"),
                           _ordered_pair("LANE_YELLOW_HUE"))
