"""``vehicle calibrate``: find the PWM values of a steering servo or an ESC, and save them."""

from __future__ import annotations

import argparse
import sys
from contextlib import AbstractContextManager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from vehicle.app.carconfig import add_car_options, car_folder, load_for_command
from vehicle.errors import UserError
from vehicle.vehicle import STOP_SIGNALS, handling

if TYPE_CHECKING:
    from vehicle.config import Config


def _address(text: str) -> int:
    try:
        return int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an I2C address; write it like 0x40") from None


def register(sub: argparse._SubParsersAction) -> None:
    """Add the calibrate subcommand."""
    p = sub.add_parser(
        "calibrate", help="find steering / throttle PWM values on a PCA9685 channel",
        description="Send pulses to one PCA9685 channel interactively to find STEERING_LEFT_PWM, "
        "STEERING_RIGHT_PWM and THROTTLE_FORWARD/STOPPED/REVERSE_PWM. Put the car on a stand: the "
        "wheels must be free. The channel returns to neutral however the tool ends. Bus, address and "
        "frequency default to the car's settings (--car).")
    p.add_argument("--channel", type=int, required=True, help="PCA9685 channel 0-15")
    p.add_argument("--bus", type=int, default=None, help="I2C bus number (default: the car's "
                   "PCA9685_I2C_BUSNUM, else 1)")
    p.add_argument("--address", type=_address, default=None, help="I2C address (default: the car's "
                   "PCA9685_I2C_ADDR, else 0x40)")
    p.add_argument("--freq", type=int, default=None, help="PWM frequency in Hz (default: the car's "
                   "PWM_FREQ, else 60)")
    p.add_argument("--neutral", type=int, default=None, help="ticks to start and end at (default: "
                   "THROTTLE_STOPPED_PWM on the throttle channel, the steering midpoint on the steering "
                   "channel, else 370)")
    p.add_argument("--step", type=int, default=10, help="ticks moved by + and -")
    add_car_options(p)
    p.add_argument("--save", action="store_true", help="write the recorded values into myconfig.py "
                   "without asking")
    p.add_argument("--mock", action="store_true", help="use a simulated PCA9685 (try the tool without "
                   "hardware)")
    p.set_defaults(func=_calibrate)


def _default_neutral(cfg: Config, channel: int) -> int:
    if channel == cfg.THROTTLE_CHANNEL:
        return cfg.THROTTLE_STOPPED_PWM
    if channel == cfg.STEERING_CHANNEL:
        from parts.actuators.pwm import map_range

        return map_range(0.0, -1.0, 1.0, cfg.STEERING_LEFT_PWM, cfg.STEERING_RIGHT_PWM)
    return 370  # the starting value of Oršolić's thesis (Building a self-driving RC car, 2020)


def _signals_exit() -> AbstractContextManager[None]:
    """SIGTERM / SIGHUP (ssh drop) raise SystemExit, so the session's neutral-on-exit still runs."""
    def leave(signum: int, _frame: Any) -> None:
        raise SystemExit(128 + signum)

    return handling(STOP_SIGNALS, leave)


def _reader() -> Any:
    """A signal-friendly line reader on stdin's descriptor; plain input() if stdin has none."""
    from parts.actuators.pwm_calibration import LineReader

    try:
        sys.stdin.fileno()
    except (AttributeError, OSError, ValueError):  # io.UnsupportedOperation is both
        return input
    return LineReader()


def _calibrate(args: argparse.Namespace) -> int:
    from parts.actuators.fake_pca9685 import mock_board
    from parts.actuators.pca9685 import PCA9685, PCA9685Error, busnum
    from parts.actuators.pwm_calibration import CalibrationSession

    if not 0 <= args.channel <= 15:
        raise UserError(f"--channel {args.channel}: a PCA9685 has channels 0-15")
    if not 1 <= args.step <= 100:
        raise UserError(f"--step {args.step}: use 1-100 ticks")
    from vehicle.config import Config, ConfigError

    try:
        cfg = load_for_command(args)
    except ConfigError as exc:
        # calibrating needs only bus, address and channels: a bad setting elsewhere (often the very
        # PWM value being calibrated) must not block it
        print(f"warning: {exc}\nwarning: using the default settings; pass --bus/--address/--freq "  # noqa: T201
              "if yours differ", file=sys.stderr)
        cfg = Config.defaults(CAR_PATH=str(car_folder(args)))
    car = Path(cfg.CAR_PATH)
    bus = busnum(cfg) if args.bus is None else args.bus
    address = cfg.PCA9685_I2C_ADDR if args.address is None else args.address
    freq = cfg.PWM_FREQ if args.freq is None else args.freq
    factory = mock_board(cfg.replace(PCA9685_I2C_BUSNUM=bus, PCA9685_I2C_ADDR=address))[0] \
        if args.mock else None
    try:
        driver = PCA9685(bus, address, freq, osc_hz=cfg.PCA9685_OSC_HZ, bus_factory=factory)
        neutral = _default_neutral(cfg, args.channel) if args.neutral is None else args.neutral
        # no I/O yet: checks the neutral value against the safe range
        session = CalibrationSession(driver, args.channel, neutral, step=args.step, read=_reader())
    except ValueError as exc:
        raise UserError(str(exc)) from exc
    interrupted = False
    try:
        driver.open()
        with _signals_exit():
            session.run()
    except KeyboardInterrupt:
        interrupted = True
        print(f"\ninterrupted: channel {args.channel} is back at neutral ({session.neutral})")  # noqa: T201
    except (PCA9685Error, ValueError) as exc:
        raise UserError(str(exc)) from exc
    finally:
        driver.close()
    found = session.found
    if not found:
        print("nothing recorded; myconfig.py unchanged")  # noqa: T201
        return 130 if interrupted else 0
    values: dict[str, Any] = dict(found)
    # the values belong to this channel, bus, address and frequency: save those that differ
    for prefix in ("STEERING", "THROTTLE"):
        if any(k.startswith(prefix) for k in found) and cfg[f"{prefix}_CHANNEL"] != args.channel:
            values[f"{prefix}_CHANNEL"] = args.channel
    for name, value in (("PCA9685_I2C_BUSNUM", bus), ("PCA9685_I2C_ADDR", address), ("PWM_FREQ", freq)):
        if value != (busnum(cfg) if name == "PCA9685_I2C_BUSNUM" else cfg[name]):
            values[name] = value
    print("recorded:\n" + "\n".join(f"  {k} = {v}" for k, v in values.items()))  # noqa: T201
    _save(car / (getattr(args, 'myconfig', None) or 'myconfig.py'), values, args.save, interrupted)
    return 130 if interrupted else 0


def _save(path: Path, values: dict[str, Any], save: bool, interrupted: bool) -> None:
    from parts.actuators.config_writer import update_myconfig

    if not save:
        if interrupted or not sys.stdin.isatty():
            print(f"not saved: copy these lines into {path}, or run with --save")  # noqa: T201
            return
        try:
            answer = input(f"Write these values to {path}? [y/N] ").strip().lower()
        except EOFError:
            answer = ""
        if answer not in ("y", "yes"):
            print("not saved")  # noqa: T201
            return
    if not path.is_file():
        raise UserError(f"{path} does not exist: pass --car with your car folder (made by "
                        "`vehicle createcar`), or copy the values above by hand")
    try:
        for line in update_myconfig(path, values):
            print(f"  {line}")  # noqa: T201
    except ValueError as exc:
        raise UserError(str(exc)) from exc
    print(f"saved to {path}")  # noqa: T201
