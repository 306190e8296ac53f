#!/usr/bin/env python3
"""Drive, record and train this car in a simulator: ours (built in), Udacity's or Donkey's.

    python manage.py drive                            # drive from the web page, record tubs
    python manage.py drive --model models/pilot.pt    # drive with a pilot (the Mode button engages it)
    python manage.py drive --model models/pilot.pt --mode local    # the pilot drives from the start
    python manage.py drive --expert --record-records 3000 --tracks 1,2,3
                                                      # record demonstrations, no human needed
    python manage.py drive --sim udacity              # drive the Udacity simulator (Autonomous Mode)
    python manage.py drive --sim donkey               # drive the Donkey simulator at SIM_HOST:SIM_PORT
    python manage.py drive --expert --record-records 6000 --lane-changes 40
                                                      # ... changing lanes (SIM_LANES = 2)
    python manage.py train --tubs data --model models/pilot.pt
    python manage.py console                          # datasets, training, models in the browser

Settings live in myconfig.py (overrides of the defaults; see docs/config.md). To add a part of
your own, insert a V.add(...) between two helper calls in drive().
"""

from pathlib import Path

from vehicle import Vehicle
from vehicle.app import assembly, manage
from vehicle.app.record import record_expert
from vehicle.errors import UserError


def drive(cfg, args):
    """Assemble the simulated car and drive it until Ctrl-C (or --max-loops)."""
    if args.expert:
        return record_demonstrations(cfg, args)
    if args.record_records or args.lane_changes:
        raise UserError("--record-records and --lane-changes are for the expert: add --expert")
    cfg = manage.start_mode(cfg, args.mode, args.model)  # --mode: who drives from the first loop
    V = Vehicle(clock=assembly.sim_clock(cfg, args.sim))  # SIM_REALTIME = False: as fast as the CPU allows
    assembly.add_simulator(V, cfg, seeds=args.tracks, sim_type=args.sim)  # angle, throttle -> cam/image_array, sim/*
    assembly.add_controller(V, cfg)  # web page (and gamepad) -> user/angle, user/throttle, user/mode
    assembly.add_camera_watchdog(V, cfg)  # a stalled Udacity/Donkey simulator takes the pilot out
    assembly.add_behavior(V, cfg)  # TRAIN_BEHAVIORS: lane buttons -> behavior/state, behavior/one_hot_state_array
    if args.model:
        assembly.add_pilot(V, cfg, args.model)  # cam/image_array -> pilot/angle, pilot/throttle
    assembly.add_drive_mode(V, cfg)  # user/* or pilot/* -> angle, throttle
    assembly.add_speed_limit(V, cfg)  # the web page's speed limit, in every mode -> throttle
    assembly.add_obstacle_stop(V, cfg)  # OBSTACLE_STOP: LiDAR sees something close ahead -> brake
    assembly.add_tub_writer(V, cfg)  # records every loop while `recording` is on
    assembly.add_simulator_commands(V)  # last: Udacity/Donkey get this loop's angle, throttle at once
    assembly.add_telemetry(V, cfg)  # MQTT_TELEMETRY: the car's status and MQTT_KEYS to your broker
    return manage.run(V, cfg, args.max_loops)


def record_demonstrations(cfg, args):
    """Let the built-in expert drive in simulated time and record --record-records N records."""
    if not args.record_records:
        raise UserError("--expert records demonstrations: add --record-records N (e.g. 3000)")
    if (args.sim or cfg.SIM_TYPE) != "builtin":
        raise UserError("--expert drives the built-in simulator only: drop --sim (or set SIM_TYPE = \"builtin\")")
    tub = record_expert(cfg, args.tracks, args.record_records, lane_changes=args.lane_changes)
    print(f"recorded {args.record_records} expert records into {tub}")
    return 0


def main(argv=None):
    parser = manage.command_parser(__doc__)
    d = manage.add_command(parser, "drive", drive, "drive the simulated car and record tubs")
    d.add_argument("--model", help="trained pilot to drive with (a models/*.pt file)")
    manage.add_mode_option(d)  # --mode user|local_angle|local
    d.add_argument("--expert", action="store_true", help="let the built-in expert drive and record (simulated time)")
    d.add_argument("--record-records", type=manage.positive_int, metavar="N", help="with --expert: records to write")
    d.add_argument("--lane-changes", type=manage.non_negative_int, metavar="N",
                   help="with --expert: change lanes N times at random")
    d.add_argument("--tracks", type=manage.int_list, metavar="SEEDS", help="track seeds, e.g. 1,2,3")
    d.add_argument("--sim", choices=["builtin", "udacity", "donkey"], help="simulator to drive (default: SIM_TYPE)")
    d.add_argument("--max-loops", type=manage.positive_int, metavar="N", help="stop after N loops")
    d.add_argument("--js", action="store_true", help="drive with the gamepad too, this run (USE_JOYSTICK_AS_DEFAULT)")
    manage.add_train_command(parser)  # the options of `vehicle train`, on this car's data/
    manage.add_console_command(parser)  # the trainer console: datasets, training, models, leaderboard
    return manage.main(parser, Path(__file__).resolve().parent, argv)


if __name__ == "__main__":
    raise SystemExit(main())
