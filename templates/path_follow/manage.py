#!/usr/bin/env python3
"""Path follow: drive a route once while the car records where it is, then let it follow the route.

    python manage.py drive                  # on the car: encoder and/or GPS, gamepad or web page
    python manage.py drive --sim            # the same in the built-in simulator (simulated sensors)
    python manage.py drive --mode local     # follow the saved path from the first loop
    python manage.py expert-path --track 1  # simulator: the expert drives one lap, saved as the path

Recording (user mode, you drive): press the record button (TOGGLE_RECORDING_BTN, or "record" on the
driver page) and drive the route; press it again to stop, then save (SAVE_PATH_BTN) to
PATH_FILENAME. To follow: put the car where the route starts, reset the origin (RESET_ORIGIN_BTN)
if the localiser is odometry, load (LOAD_PATH_BTN; the file is loaded at start too) and switch to
local mode (the mode button): the follower steers and drives, the e-stop and every safety path
work as with a learned pilot. See docs/path_follow.md; settings in myconfig.py (docs/config.md).
"""

from pathlib import Path

from vehicle import Vehicle
from vehicle.app import assembly, manage
from vehicle.app.path_sim import record_path, sensor_config


def drive(cfg, args):
    """Assemble the path-follow car (or the simulated one) and drive until Ctrl-C (or --max-loops)."""
    if args.mode:  # the path is the pilot: no model file needed
        cfg = cfg.replace(DEFAULT_MODE=args.mode)
    if args.sim:
        cfg = sensor_config(cfg, cfg.PATH_LOCALIZER)  # the simulated encoder / GPS the localiser needs
        V = Vehicle(clock=assembly.sim_clock(cfg, "builtin"))
        assembly.add_simulator(V, cfg, seeds=args.tracks, sim_type="builtin")  # -> sim/*, enc/*, pos/*, gps/*
    else:
        V = Vehicle()
        assembly.add_sensors(V, cfg)  # HAVE_ODOM, HAVE_GPS, HAVE_IMU -> enc/*, pos/*, gps/*
    assembly.add_controller(V, cfg)  # web page (and gamepad) -> user/angle, user/throttle, user/mode
    assembly.add_path_follow(V, cfg)  # path buttons, localiser, recorder, follower -> pilot/angle, pilot/throttle
    assembly.add_drive_mode(V, cfg)  # user/* or pilot/* -> angle, throttle
    assembly.add_speed_limit(V, cfg)  # the web page's speed limit, in every mode -> throttle
    assembly.add_obstacle_stop(V, cfg)  # OBSTACLE_STOP: LiDAR sees something close ahead -> brake
    if not args.sim:
        assembly.add_throttle_filter(V, cfg)  # ESC reverse double-tap
        assembly.add_drivetrain(V, cfg)  # angle, throttle -> PWM
    assembly.add_telemetry(V, cfg)  # MQTT_TELEMETRY: the car's status and MQTT_KEYS to your broker
    return manage.run(V, cfg, args.max_loops)


def expert_path(cfg, args):
    """Let the simulator's expert drive one lap of --track and save it as the path (PATH_FILENAME)."""
    from parts.path.pathfile import save_path

    path = record_path(cfg, args.track, cfg.PATH_LOCALIZER)
    print(f"recorded {len(path)} points ({path.length:.1f} m) with {cfg.PATH_LOCALIZER}: "  # noqa: T201
          f"wrote {save_path(path, cfg.path('PATH_FILENAME'))}")
    return 0


def main(argv=None):
    parser = manage.command_parser(__doc__)
    d = manage.add_command(parser, "drive", drive, "drive, record a path, follow it")
    d.add_argument("--sim", action="store_true", help="drive the built-in simulator with its simulated sensors")
    d.add_argument("--mode", choices=["user", "local_angle", "local"],
                   help="who drives from the first loop: user (you) or local (the path follower)")
    d.add_argument("--tracks", type=manage.int_list, metavar="SEEDS", help="with --sim: track seeds, e.g. 1")
    d.add_argument("--max-loops", type=manage.positive_int, metavar="N", help="stop after N loops")
    d.add_argument("--js", action="store_true", help="drive with the gamepad too, this run (USE_JOYSTICK_AS_DEFAULT)")
    e = manage.add_command(parser, "expert-path", expert_path, "simulator: record one lap driven by the expert")
    e.add_argument("--track", type=int, default=1, help="track seed")
    return manage.main(parser, Path(__file__).resolve().parent, argv)


if __name__ == "__main__":
    raise SystemExit(main())
