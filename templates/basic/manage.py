#!/usr/bin/env python3
"""Drive, record and train this car: camera, controller, PWM drivetrain, tub writer, pilot.

    python manage.py drive                            # drive from the web page or gamepad, record tubs
    python manage.py drive --model models/pilot.pt    # drive with a pilot (the Mode button engages it)
    python manage.py drive --model models/pilot.pt --mode local    # the pilot drives from the start
    python manage.py train --tubs data --model models/pilot.pt
    python manage.py console                          # datasets, training, models in the browser

Settings live in myconfig.py (overrides of the defaults; see docs/config.md); set CAMERA_TYPE and
DRIVE_TRAIN_TYPE to "MOCK" to run on the bench without hardware. To add a part of your own,
insert a V.add(...) between two helper calls in drive().
"""

from pathlib import Path

from vehicle import Vehicle
from vehicle.app import assembly, manage


def drive(cfg, args):
    """Assemble the car and drive it until Ctrl-C (or --max-loops)."""
    cfg = manage.start_mode(cfg, args.mode, args.model)  # --mode: who drives from the first loop
    V = Vehicle()
    assembly.add_camera(V, cfg)  # -> cam/image_array, cam/timestamp, cam/ok
    assembly.add_sensors(V, cfg)  # HAVE_ODOM, HAVE_IMU, HAVE_GPS, USE_LIDAR -> enc/*, pos/*, imu/*, gps/*, lidar/*
    assembly.add_controller(V, cfg)  # web page (and gamepad) -> user/angle, user/throttle, user/mode
    assembly.add_camera_watchdog(V, cfg)  # camera stalled -> user mode, throttle 0: no pilot without frames
    assembly.add_behavior(V, cfg)  # -> behavior/state, behavior/label, behavior/one_hot_state_array
    if args.model:
        assembly.add_pilot(V, cfg, args.model)  # cam/image_array -> pilot/angle, pilot/throttle
    assembly.add_drive_mode(V, cfg)  # user/* or pilot/* -> angle, throttle
    assembly.add_speed_limit(V, cfg)  # the web page's speed limit, in every mode -> throttle
    assembly.add_obstacle_stop(V, cfg)  # OBSTACLE_STOP: LiDAR sees something close ahead -> brake
    assembly.add_throttle_filter(V, cfg)  # ESC reverse double-tap
    assembly.add_drivetrain(V, cfg)  # angle, throttle -> PCA9685 pulses
    assembly.add_recording_rules(V, cfg)  # auto-record on throttle, no recording in autopilot
    assembly.add_tub_writer(V, cfg)  # records every loop while `recording` is on
    assembly.add_telemetry(V, cfg)  # MQTT_TELEMETRY: the car's status and MQTT_KEYS to your broker
    return manage.run(V, cfg, args.max_loops)


def main(argv=None):
    parser = manage.command_parser(__doc__)
    d = manage.add_command(parser, "drive", drive, "drive the car and record tubs")
    d.add_argument("--model", help="trained pilot to drive with (a models/*.pt file)")
    manage.add_mode_option(d)  # --mode user|local_angle|local
    d.add_argument("--max-loops", type=manage.positive_int, metavar="N", help="stop after N loops")
    d.add_argument("--js", action="store_true", help="drive with the gamepad too, this run (USE_JOYSTICK_AS_DEFAULT)")
    manage.add_train_command(parser)  # the options of `vehicle train`, on this car's data/
    manage.add_console_command(parser)  # the trainer console: datasets, training, models, leaderboard
    return manage.main(parser, Path(__file__).resolve().parent, argv)


if __name__ == "__main__":
    raise SystemExit(main())
