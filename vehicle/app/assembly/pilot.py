"""Assembly of the pilot: drive with a trained model (``add_pilot``)."""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from vehicle.config import Config
from vehicle.errors import UserError, WiringError

logger = logging.getLogger(__name__)


#: what to do about a model trained on frames of another size than a camera's (or the Donkey
#: simulator's, which it renders at IMAGE_W x IMAGE_H), the built-in simulator's, the Udacity simulator's
IMAGE_SIZE_HINT = "set IMAGE_W/IMAGE_H to the training size or re-train"
SIM_SIZE_HINT = "set SIM_CAMERA_W/SIM_CAMERA_H to the training size or re-train"
UDACITY_SIZE_HINT = ("the Udacity simulator's frames are always 320x160: train on tubs recorded in it, or on its "
                     "driving_log.csv (vehicle tub import-udacity)")


BEHAVIOR_KEY = "behavior/one_hot_state_array"


def pilot_inputs(pilot: Any) -> tuple[str, ...]:
    """The memory keys a pilot part reads (``INPUTS`` of a class, ``inputs`` of a loaded model)."""
    return tuple(getattr(pilot, "INPUTS", None) or getattr(pilot, "inputs", None) or ())


def check_behavior_input(pilot: Any, cfg: Config) -> None:
    """UserError when the pilot reads the behaviour and the car, without TRAIN_BEHAVIORS, makes
    none: the message says which setting to change (the vehicle's wiring check would name the
    key and ``optional_inputs``, which is for whoever writes parts).

    Call it where nothing else gives the pilot its behaviour (no part makes it, no value seeded).
    """
    if BEHAVIOR_KEY not in pilot_inputs(pilot) or cfg.TRAIN_BEHAVIORS:
        return
    trained = (getattr(pilot, "meta", None) or {}).get("training", {}).get("behaviors")
    name = getattr(pilot, "model_name", None) or type(pilot).__name__
    raise UserError(f"{name} reads the behaviour ({BEHAVIOR_KEY}; trained with "
                    f"{trained or 'unnamed behaviours'}), which this car does not make: set TRAIN_BEHAVIORS = True "
                    "in myconfig.py")


#: what to do about a model of several camera views (three_camera) in a car that lacks some,
#: by what makes the car's frames
VIEWS_HINTS = {
    "builtin": "set SIM_SIDE_CAMERAS_OFFSET in myconfig.py (the offset in metres its tubs were recorded with)",
    "udacity": "the Udacity simulator sends only the centre frame while driving (it records the side cameras "
               "but never streams them): drive this model in the built-in simulator with SIM_SIDE_CAMERAS_OFFSET, "
               "or train a single-camera model on the same tubs (e.g. --recipe track-driver-ai, which learns "
               "from the side frames as extra samples)",
    "donkey": "the Donkey simulator sends one camera: drive this model in the built-in simulator with "
              "SIM_SIDE_CAMERAS_OFFSET, or train a single-camera model",
    "car": "this car has one camera: give it parts that write the side frames, or train a single-camera model "
           "(e.g. pilotnet with TRAIN_SIDE_CAMERAS, which learns from the side frames as extra samples)",
}


def check_views(name: str, image_inputs: Sequence[str], available: Callable[[str], bool], car: str) -> None:
    """Raise WiringError (one line: what is missing, why, what to do) unless the car makes every
    camera frame of ``image_inputs``; ``car`` is a key of :data:`VIEWS_HINTS`."""
    missing = [key for key in image_inputs if not available(key)]
    if missing:
        raise WiringError(f"{name} takes the frames {', '.join(image_inputs)} together, but this car makes no "
                          f"{' and no '.join(missing)}: {VIEWS_HINTS[car]}")


def frames_source(V: Any) -> str:
    """What makes a vehicle's camera frames: "builtin", "udacity", "donkey" (simulators) or "car"."""
    from parts.bridges.donkey_client import DonkeySim
    from parts.bridges.udacity_sim import UdacitySim
    from parts.sim.simulator import SimCar

    for kind, cls in (("builtin", SimCar), ("udacity", UdacitySim), ("donkey", DonkeySim)):
        if V.find(cls):
            return kind
    return "car"


def add_pilot(V: Any, cfg: Config, model_path: str | Path) -> Any:
    """Add PilotCondition (``user/mode`` -> ``run_pilot``), the model switcher and the Pilot.

    The pilot runs only while ``run_pilot`` is True and reads the inputs its model file declares
    (``cam/image_array`` first; the three-camera model's side frames are refused, with what to do,
    where the car makes none); it outputs ``pilot/angle`` and ``pilot/throttle``. A
    :class:`parts.pilots.pilot.ModelSwitch` (every loop) loads the model named in
    ``pilot/model_request`` in the background and outputs ``pilot/model``. With
    PILOT_SPEED_CONTROL and PILOT_SPEED_LIMIT set, a speed controller replaces the model's throttle
    by one that drives at PILOT_SPEED_LIMIT. (The web page's speed limit caps the final throttle in
    every mode: :func:`vehicle.app.assembly.drive.add_drive_mode`.)
    Returns the Pilot.

    Raises:
        UserError: the model file is missing, unreadable, or the backend setting cannot be met.
        WiringError: the model takes camera frames the car does not make (:func:`check_views`).
    """
    from parts.drive.modes import PilotCondition
    from parts.pilots.pilot import ModelSwitch

    frame_shape, frame_hint = camera_frames(V)
    pilot = make_pilot(cfg, model_path, measured_speed_key=speed_key_of(V, cfg), frame_shape=frame_shape,
                       frame_hint=frame_hint)
    try:  # a three-camera model needs the side frames
        check_views(pilot.model_name, pilot.runner.image_inputs, lambda k: V.produces(k) or k in V.mem,
                    frames_source(V))
    except WiringError:
        pilot.shutdown()
        raise
    if not V.produces(BEHAVIOR_KEY) and BEHAVIOR_KEY not in V.mem:
        try:
            check_behavior_input(pilot, cfg)
        except UserError:
            pilot.shutdown()
            raise
    V.add(PilotCondition())
    V.add(ModelSwitch(pilot))
    pilot.lock_inputs = True  # the vehicle's wiring is fixed from here on
    V.add(pilot, run_condition="run_pilot")
    return pilot


def check_model_file(V: Any, cfg: Config, path: str | Path) -> None:
    """Raise ValueError (a UserError) with the reason unless the model file ``path`` fits this car:
    with a pilot in ``V``, the checks of a hot switch to it (:meth:`parts.pilots.pilot.Pilot.check_file`);
    without, those of ``manage.py drive --model`` (:func:`make_pilot` with the car's frames). A model
    pushed from the laptop (:mod:`parts.web.carlink`) is checked so before it is kept."""
    from parts.pilots.pilot import Pilot

    pilot = V.find(Pilot)
    if pilot:
        pilot[0].check_file(path)
        return
    frame_shape, frame_hint = camera_frames(V)
    make_pilot(cfg, path, measured_speed_key=speed_key_of(V, cfg), frame_shape=frame_shape,
               frame_hint=frame_hint).shutdown()


def make_pilot(cfg: Config, model_path: str | Path, measured_speed_key: str = "enc/speed",
               frame_shape: tuple[int, int, int] | None = None, frame_hint: str = IMAGE_SIZE_HINT) -> Any:
    """The Pilot part for a model file with the car's settings: back-end (PILOT_BACKEND,
    PILOT_ONNX_THREADS) and speed control (PILOT_SPEED_*), exactly as the car drives with it.

    The model must fit the car (:mod:`parts.pilots.compat`): a behaviour model's stored behaviour
    order must be BEHAVIOR_LIST's, and a model trained on undistorted frames needs
    CAMERA_UNDISTORT (and the other way round); the same holds for every hot switch.

    ``measured_speed_key`` is where the car's speed comes from when PILOT_SPEED_KEY is not set: the
    simulator's ``sim/speed``, or ``enc/speed`` from an encoder part. A relative path that does not
    exist here is looked up in the car folder (manage.py may run from another folder).
    ``frame_shape`` (height, width, 3) of the camera frames: a model trained on others, or whose
    extra inputs do not fit BEHAVIOR_LIST, is refused here (None: checked at the first frame);
    ``frame_hint`` says what to do then (see :func:`camera_frames`).

    A model file registered in the car's model database (or the one next to it) must still have the
    bytes it was registered with, here and at each hot switch (:func:`registered_check`).

    Raises:
        UserError: the model file is missing, unreadable, does not fit the car, or the backend
            setting cannot be met.
        training.model_db.ModelChanged: a registered model file changed since it was registered.
    """
    from parts.pilots import load_pilot
    from parts.pilots.compat import CarInputs

    path = Path(model_path)
    if not path.is_absolute() and not path.exists():
        path = Path(cfg.CAR_PATH) / path
    from parts.drive.speed import SpeedControl

    speed_control = None
    speed_key = cfg.PILOT_SPEED_KEY or measured_speed_key
    # drives to the target speed of a model trained on speeds (TRAIN_THROTTLE_LABEL = "speed")
    target_control = SpeedControl("pi", dt=1.0 / cfg.DRIVE_LOOP_HZ, kp=cfg.PILOT_SPEED_KP, ki=cfg.PILOT_SPEED_KI,
                                  max_throttle=cfg.PILOT_SPEED_MAX_THROTTLE)
    if cfg.PILOT_SPEED_CONTROL != "off":
        speed_control = SpeedControl(cfg.PILOT_SPEED_CONTROL, dt=1.0 / cfg.DRIVE_LOOP_HZ,
                                     kp=cfg.PILOT_SPEED_KP, ki=cfg.PILOT_SPEED_KI,
                                     max_throttle=cfg.PILOT_SPEED_MAX_THROTTLE,
                                     default_limit=cfg.PILOT_SPEED_LIMIT,
                                     headroom=cfg.PILOT_SPEED_LIMIT_HEADROOM)
    try:
        return load_pilot(path, backend=cfg.PILOT_BACKEND, speed_control=speed_control, speed_key=speed_key,
                          onnx_threads=cfg.PILOT_ONNX_THREADS, models_dir=cfg.path("MODELS_PATH"),
                          frame_shape=frame_shape, frame_hint=frame_hint,
                          extra_sizes={"behavior/one_hot_state_array": len(cfg.BEHAVIOR_LIST)},
                          car=CarInputs.from_config(cfg), target_control=target_control,
                          verify=registered_check(cfg))
    except (ValueError, ImportError, OSError) as exc:
        raise UserError(f"cannot drive with {path}: {exc}") from exc


def registered_check(cfg: Config) -> Callable[[Path], None]:
    """The pilot's check of each model file it loads: refused (ModelChanged, one line) when it is
    registered in the car's model database (MODELS_PATH) or in the one next to it, and its bytes
    are no longer those it was registered with (another intact model under its name)."""
    from training.model_db import check_registered

    models_dir = cfg.path("MODELS_PATH")
    return lambda path: check_registered(path, models_dir)


def speed_key_of(V: Any, cfg: Config) -> str:
    """PILOT_SPEED_KEY, else enc/speed when a part measures it (an odometer, a VESC, the GPS's
    speed, a simulator's reported speed), else sim/speed when a simulator is in ``V``, else
    enc/speed (a real car needs a speed source writing it)."""
    if cfg.PILOT_SPEED_KEY:
        return cfg.PILOT_SPEED_KEY
    if V.produces("enc/speed"):
        return "enc/speed"
    return "sim/speed" if V.produces("sim/speed") else "enc/speed"


def camera_frames(V: Any) -> tuple[tuple[int, int, int] | None, str]:
    """(height, width, 3) of the ``cam/image_array`` frames the pilot will get, as the part that
    makes them declares (``OUTPUT_SHAPES``: a camera, the simulator's camera, the Udacity
    simulator's fixed frames), or None when it does not (the Donkey simulator: the pilot then
    learns the size from the first frame); and what to do about a model trained on frames of
    another size."""
    from parts.bridges.udacity_sim import UdacitySim
    from parts.sim.simulator import SimCar
    from vehicle.shapes import declared_shapes

    for entry in reversed(getattr(V, "parts", ())):
        if "cam/image_array" in entry.outputs:
            hint = SIM_SIZE_HINT if isinstance(entry.part, SimCar) else \
                UDACITY_SIZE_HINT if isinstance(entry.part, UdacitySim) else IMAGE_SIZE_HINT
            shape = declared_shapes(entry.part, "OUTPUT_SHAPES", "OUTPUTS", entry.outputs).get("cam/image_array")
            if shape is not None and len(shape) == 3 and all(isinstance(d, int) for d in shape):
                return (shape[0], shape[1], shape[2]), hint
            return None, hint
    return None, IMAGE_SIZE_HINT


def sim_frames(cfg: Config, sim: str) -> tuple[tuple[int, int, int] | None, str]:
    """:func:`camera_frames` for a car in simulator ``sim`` ("builtin", "udacity", "donkey"), before
    the car is built: the Donkey simulator's size is learnt from its first frame."""
    if sim == "builtin":
        return (cfg.SIM_CAMERA_H, cfg.SIM_CAMERA_W, 3), SIM_SIZE_HINT
    if sim == "udacity":
        from parts.bridges.udacity_protocol import FRAME_SIZE

        return (FRAME_SIZE[1], FRAME_SIZE[0], 3), UDACITY_SIZE_HINT
    return None, IMAGE_SIZE_HINT
