"""``vehicle drivetrain check``: move the car's drivetrain through a short script on the bench.

    vehicle drivetrain check                   # the car in the current folder, DRIVE_TRAIN_TYPE from myconfig.py
    vehicle drivetrain check --throttle 0.15 --seconds 2

Put the car on a stand with the wheels off the ground first. The command opens the drivetrain the
car's settings describe (PCA9685, GPIO pins, VESC, Robo HAT MM1), then steps through: neutral
(the ESC arms), full left, full right, centre, forward at --throttle, neutral, reverse, neutral,
printing what you should see at each step (a VESC with VESC_GEAR_RATIO also prints the measured
speed). With GPIO_MOCK = True a car with GPIO pins runs on simulated pins (no GPIO needed, nothing
moves) and each step ends with what every pin would have output. It runs in the normal drive
loop, so Ctrl-C, the command watchdog and every stop path leave the drivetrain at neutral, as
when driving.
"""

from __future__ import annotations

import argparse
import logging
from typing import Any, ClassVar

from vehicle.app.carconfig import add_car_options, load_for_command
from vehicle.errors import UserError

logger = logging.getLogger(__name__)


def register(subparsers: Any) -> None:
    """Add the ``drivetrain`` command and its ``check`` subcommand."""
    cmd = subparsers.add_parser("drivetrain", help="check the car's drivetrain on the bench",
                                description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = cmd.add_subparsers(dest="drivetrain_command", metavar="SUBCOMMAND", required=True)
    check = sub.add_parser("check", help="steer and drive through a short script, wheels off the ground",
                           description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    check.add_argument("--throttle", type=float, default=0.2, help="throttle of the forward and reverse steps "
                                                                   "(0-0.5; default 0.2)")
    check.add_argument("--seconds", type=float, default=1.5, help="seconds per step (default 1.5)")
    check.add_argument("--yes", action="store_true", help="do not ask whether the wheels are off the ground")
    add_car_options(check)
    check.set_defaults(func=cmd_check)


def steps(throttle: float, seconds: float, arm_s: float) -> list[tuple[str, float, float, float]]:
    """The bench script: (what to see, angle, throttle, seconds) per step."""
    return [
        ("neutral: the ESC arms (beeps), steering centred", 0.0, 0.0, max(arm_s, 0.0) + seconds),
        ("steering full LEFT", -1.0, 0.0, seconds),
        ("steering full RIGHT", 1.0, 0.0, seconds),
        ("steering centred", 0.0, 0.0, seconds),
        (f"FORWARD at throttle {throttle:g}: the wheels turn forwards", 0.0, throttle, seconds),
        ("neutral: the wheels stop", 0.0, 0.0, seconds),
        (f"REVERSE at throttle {-throttle:g} (an ESC may brake first)", 0.0, -throttle, seconds),
        ("neutral: the wheels stop", 0.0, 0.0, seconds),
    ]


class BenchScript:
    """A part that outputs the script's (angle, throttle) on the loop's clock and says each step;
    it stops the vehicle after the last step. Reads ``enc/speed`` (a VESC's) from the loop before,
    when a part makes it."""

    INPUTS: ClassVar[tuple[str, ...]] = ("enc/speed",)
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("enc/speed",)
    FEEDBACK: ClassVar[tuple[str, ...]] = ("enc/speed",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("angle", "throttle")

    def __init__(self, V: Any, script: list[tuple[str, float, float, float]], say: Any = print,
                 report: Any = None) -> None:
        self.V = V
        self.script = script
        self.say = say
        self.report = report  # () -> a line said at the end of each step (what the outputs were)
        self.index = -1
        self.until = 0.0
        self.speeds: list[float] = []

    def run(self, speed: float | None = None) -> tuple[float, float]:
        now = self.V.clock.now()
        if self.index < 0 or now >= self.until:
            if self.index >= 0 and self.report is not None:
                self.say(self.report())
            self.index += 1
            if self.index >= len(self.script):
                self.V.stop()
                return 0.0, 0.0
            text, _, _, seconds = self.script[self.index]
            self.until = now + seconds
            self.say(f"[{self.index + 1}/{len(self.script)}] {text}")
        if speed is not None:
            self.speeds.append(speed)
        _, angle, throttle, _ = self.script[self.index]
        return angle, throttle


def cmd_check(args: argparse.Namespace) -> int:
    """Run the bench script on the car's drivetrain."""
    from vehicle import Vehicle
    from vehicle.app.assembly.drivetrain import add_drivetrain

    if not 0 < args.throttle <= 0.5:
        raise UserError(f"--throttle {args.throttle}: give 0 < throttle <= 0.5 (a bench check needs little)")
    if not 0.05 <= args.seconds <= 10:
        raise UserError(f"--seconds {args.seconds}: give 0.05 to 10 seconds per step")
    cfg = load_for_command(args)
    if not args.yes:
        try:
            answer = input(f"DRIVE_TRAIN_TYPE = {cfg.DRIVE_TRAIN_TYPE}: are the wheels off the ground? [y/N] ")
        except EOFError:  # standard input is not a terminal (a script, a service): nobody can answer
            raise UserError("no answer to 'are the wheels off the ground?' (standard input is not a terminal): "
                            "put the car on a stand and add --yes; nothing was moved") from None
        if answer.strip().lower() not in ("y", "yes"):
            print("Put the car on a stand first; nothing was moved.")  # noqa: T201 - the command's output
            return 1
    V = Vehicle()
    script = BenchScript(V, steps(args.throttle, args.seconds, cfg.ESC_ARM_TIME_S),
                         say=lambda text: print(text, flush=True))  # noqa: T201 - the command's output
    V.add(script)
    part = add_drivetrain(V, cfg)
    print(f"drivetrain: {part.describe()}", flush=True)  # noqa: T201 - the command's output
    pins = getattr(part, "pins", None)
    if cfg.GPIO_MOCK and pins is not None and pins.gpio_levels():
        print("GPIO_MOCK: the GPIO pins are simulated (gpiozero's MockFactory); nothing moves", flush=True)  # noqa: T201
        script.report = lambda: "    pins: " + ", ".join(f"{name} {level:.3f}"
                                                           for name, level in pins.gpio_levels().items())
    V.start(rate_hz=cfg.DRIVE_LOOP_HZ)
    if script.speeds:
        print(f"measured speed: {min(script.speeds):.2f} to {max(script.speeds):.2f} m/s "  # noqa: T201
              "(VESC RPM; positive forwards)")
    print("done: the drivetrain is at neutral")  # noqa: T201 - the command's output
    return 0
