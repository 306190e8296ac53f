"""``vehicle hw``: bench checks of a real car's sensors and tuning of its speed controller.

- ``vehicle hw check`` opens every sensor the car's settings switch on (HAVE_ODOM, HAVE_IMU,
  HAVE_GPS, USE_LIDAR and any kind an installed package adds), waits for readings and says in one
  line each what it sees (the part's own ``where()`` / ``describe()``). Nothing moves.
- ``vehicle hw tune-speed`` drives a throttle step straight ahead (on the floor or on blocks; or
  in the built-in simulator with ``--sim``), fits the speed response and prints PI gains.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import threading
from collections.abc import Iterator
from typing import Any

from vehicle.app.carconfig import add_car_options, load_for_command
from vehicle.errors import UserError, VehicleError


def register(sub: argparse._SubParsersAction) -> None:
    """Add the hw subcommand and its verbs."""
    p = sub.add_parser("hw", help="check a real car's sensors; tune its speed controller",
                       description="Bench checks of the sensors a car's myconfig.py switches on, and the "
                       "speed controller's step-response tuning.")
    verbs = p.add_subparsers(dest="hw_command", required=True, metavar="{check,tune-speed}")
    c = verbs.add_parser("check", help="read each configured sensor once and say what it sees",
                         description="Open every sensor the car switches on (HAVE_ODOM, HAVE_IMU, HAVE_GPS, "
                         "USE_LIDAR), wait for readings and print one line per device. Nothing moves. "
                         "Exit status 1 when a device is missing or silent.")
    add_car_options(c)
    c.add_argument("--only", metavar="KIND", help="check one kind of sensor (odom, imu, gps, lidar, or a kind an "
                   "installed package of parts adds)")
    c.add_argument("--timeout", type=float, default=3.0, help="seconds to wait for each device (default 3)")
    c.add_argument("--debug", action="store_true", help="log each device's failure with its traceback")
    c.set_defaults(func=_check)
    t = verbs.add_parser("tune-speed", help="drive a throttle step and suggest PI gains for the speed control",
                         description="Drive straight: 0.5 s neutral, a throttle step until --distance metres "
                         "or --duration seconds, then neutral; fit the measured speed (enc/speed) and print "
                         "PILOT_SPEED_KP / PILOT_SPEED_KI. Put the car on the floor with room ahead, or on "
                         "blocks. Every exit leaves the throttle at neutral.")
    add_car_options(t)
    t.add_argument("--throttle", type=float, default=0.3, help="step throttle in (0, 1] (default 0.3)")
    t.add_argument("--distance", type=float, default=4.0, help="stop after this many metres (default 4)")
    t.add_argument("--duration", type=float, default=5.0, help="stop after this many seconds (default 5)")
    t.add_argument("--sim", action="store_true", help="in the built-in simulator (speed from simulated encoder "
                   "ticks), to try the tool")
    t.add_argument("--save", action="store_true", help="write the gains into myconfig.py")
    t.set_defaults(func=_tune)


# -- check ------------------------------------------------------------------------------------
def _check(args: argparse.Namespace) -> int:
    from parts.sensors.registry import sensor_tables

    cfg = load_for_command(args)
    if args.timeout <= 0:
        raise UserError(f"--timeout {args.timeout}: give a number of seconds > 0")
    tables = sensor_tables()
    if args.only is not None:
        tables = tuple(t for t in tables if t.kind == args.only)
        if not tables:
            raise UserError(f"--only {args.only}: not a kind of sensor; the kinds are "
                            f"{', '.join(t.kind for t in sensor_tables())}")
    enabled = [t for t in tables if t.enabled(cfg)]
    if not enabled:
        which = ", ".join(str(t.enabled_by) for t in tables)
        print(f"no sensor to check: switch one on in myconfig.py ({which} = True)")  # noqa: T201
        return 1
    failed = 0
    width = max(6, *(len(t.kind) for t in enabled))
    with _one_line_per_device(args.debug):
        for table in enabled:
            ok, text = check_one(table, cfg, args.timeout)
            failed += not ok
            print(f"{table.kind:<{width}} {cfg[table.setting]} {text}")  # noqa: T201
    return 1 if failed else 0


@contextlib.contextmanager
def _one_line_per_device(debug: bool) -> Iterator[None]:
    """The check prints each device's failure in its line: the part threads' own error logs (and
    their tracebacks) only with --debug."""
    if debug:
        yield
        return
    log = logging.getLogger("vehicle.part")
    level = log.level
    log.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        log.setLevel(level)


def check_one(table: Any, cfg: Any, timeout: float) -> tuple[bool, str]:
    """(whether the device answered, one line saying what it sees) for one sensor table's part: the
    part's own ``where()`` and ``describe(values)``."""
    try:
        part = table.from_config(cfg)
    except (VehicleError, ValueError) as exc:
        return False, f"cannot be built: {exc}"
    pause = threading.Event()
    values: tuple[Any, ...] = ()
    try:
        part.start()
        for _ in range(max(1, int(timeout / 0.05))):
            if part.error is not None:
                break
            values = part.run_threaded()
            if values and values[-1] is True:
                break
            pause.wait(0.05)
        if part.error is not None:
            return False, f"{part.where()}: {part.error}"
        return part.describe(values)
    finally:
        part.shutdown()


# -- tune-speed ---------------------------------------------------------------------------------
def _tune(args: argparse.Namespace) -> int:
    from parts.drive.speed_tuning import StepTest, TuningError
    from vehicle import Vehicle

    cfg = load_for_command(args)
    if not 0 < args.throttle <= 1 or args.distance <= 0 or args.duration <= 0:
        raise UserError("--throttle must be in (0, 1], --distance and --duration > 0")
    dt = 1.0 / cfg.DRIVE_LOOP_HZ
    # neutral first, longer than the ESC's arming time (the drivetrain holds neutral while it arms)
    settle = 0.5 if args.sim else max(0.5, float(cfg.ESC_ARM_TIME_S or 0.0) + 0.3)
    test = StepTest(args.throttle, dt=dt, settle=settle, duration=args.duration, distance=args.distance)
    if args.sim:
        from vehicle.app.assembly.sim import add_simulator
        from vehicle.clock import SimulatedClock

        cfg = cfg.replace(HAVE_ODOM=True, SIM_TYPE="builtin", SIM_RESET_OFF_TRACK=False)
        V = Vehicle(clock=SimulatedClock())
        add_simulator(V, cfg)
    else:
        from vehicle.app.assembly.sensors import add_sensors

        V = Vehicle()
        add_sensors(V, cfg)
    if not V.produces("enc/speed") and args.sim is False and cfg.DRIVE_TRAIN_TYPE != "VESC":
        raise UserError("tuning needs a measured speed: set HAVE_ODOM = True (wheel encoder) or HAVE_GPS = True "
                        "in myconfig.py, or use a VESC drivetrain")
    V.add(test, feedback=["enc/speed", "enc/distance"])
    if not args.sim:
        from vehicle.app.assembly.drivetrain import add_drivetrain

        add_drivetrain(V, cfg)
    V.add(lambda done: V.stop() if done else None, inputs=["tune/done"])
    V.start(rate_hz=cfg.DRIVE_LOOP_HZ, max_loop_count=int((settle + args.duration) / dt) + 20)
    try:
        model, gains = test.result()
    except TuningError as exc:
        raise UserError(f"tune-speed: {exc}") from exc
    print(f"step {args.throttle:.2f} ({test.stopped_by} reached): final {model.final_speed:.2f} m/s, "  # noqa: T201
          f"K {model.gain:.2f} m/s per throttle, tau {model.tau:.2f} s, dead time {model.dead_time:.2f} s")
    values = {"PILOT_SPEED_KP": round(gains.kp, 3), "PILOT_SPEED_KI": round(gains.ki, 3)}
    print("\n".join(f"{k} = {v}" for k, v in values.items()))  # noqa: T201
    if args.save:
        from parts.actuators.config_writer import update_myconfig

        path = cfg.path("CAR_PATH") / (getattr(args, "myconfig", None) or "myconfig.py")
        if not path.is_file():
            raise UserError(f"{path} does not exist: pass --car with your car folder, or copy the lines above")
        for line in update_myconfig(path, values):
            print(f"  {line}")  # noqa: T201
    return 0
