"""``vehicle createjs``: map an unknown gamepad and write the mapping for CONTROLLER_TYPE = "custom"."""

from __future__ import annotations

import argparse
import sys

from vehicle.app.carconfig import add_car_options


def register(sub: argparse._SubParsersAction) -> None:
    """Add the createjs subcommand."""
    p = sub.add_parser(
        "createjs", help="map a gamepad by pressing its buttons (writes a mapping JSON)",
        description="Asks you to move the steering stick, the throttle and the buttons for each action, "
        "then writes a mapping file. Use it with CONTROLLER_TYPE = \"custom\" and "
        "JOYSTICK_MAPPING_PATH in myconfig.py.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--device", default=None,
                   help="joystick device (default: JOYSTICK_DEVICE_FILE of the car, else /dev/input/js0)")
    p.add_argument("--pygame", action="store_true", help="read the pad through pygame/SDL instead")
    p.add_argument("--index", type=int, default=0, help="with --pygame: pad index")
    p.add_argument("--out", default=None,
                   help="mapping file to write (default: JOYSTICK_MAPPING_PATH of the car)")
    add_car_options(p)
    p.add_argument("--timeout", type=float, default=30.0, help="seconds each question waits")
    p.set_defaults(func=_createjs)


def _createjs(args: argparse.Namespace) -> int:
    from pathlib import Path

    from parts.controllers.layouts import load_layout
    from parts.controllers.mapping_wizard import CreateJsWizard, WizardError, save_layout
    from vehicle.app.carconfig import load_for_command
    from vehicle.errors import UserError

    cfg = load_for_command(args)
    out = Path(args.out) if args.out else cfg.path("JOYSTICK_MAPPING_PATH")
    if args.pygame:
        from parts.controllers.pygame_js import PygameJoystick

        reader = PygameJoystick(args.index)
    else:
        from parts.controllers.linux_js import LinuxJoystick

        device = args.device or str(cfg.path("JOYSTICK_DEVICE_FILE"))
        # a FIFO/recording cannot be queried: assume the common xpad-style code order
        reader = LinuxJoystick(device, fallback_caps=load_layout("generic").caps)
    if args.timeout <= 0:
        raise UserError("--timeout must be > 0 seconds")
    wizard = CreateJsWizard(reader, sys.stdout, sys.stdin, step_timeout_s=args.timeout)
    try:
        layout = wizard.run()
    except WizardError as exc:
        raise UserError(f"createjs: {exc}") from exc
    path = save_layout(layout, out)
    print(f"wrote {path}")  # noqa: T201 - CLI output
    print("use it with these lines in myconfig.py:")  # noqa: T201
    print('    CONTROLLER_TYPE = "custom"')  # noqa: T201
    print(f'    JOYSTICK_MAPPING_PATH = "{path}"')  # noqa: T201
    return 0
