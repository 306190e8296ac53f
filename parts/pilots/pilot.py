"""The Pilot part: drives with a trained model file.

``Pilot(path).run(image, *extra_inputs) -> (angle, throttle)``. The model file says what the model
needs (``pilot.inputs``: its camera frames first, ``cam/image_array`` or, for the three-camera
model, ``cam/image_array_left``, ``cam/image_array``, ``cam/image_array_right``; then e.g.
``behavior/one_hot_state_array``);
previous commands (``memory`` models) and the last N frames (sequence models) are kept inside the
part. Frames go through the same preprocessing code as training. Outputs are clamped to [-1, 1];
a NaN or infinite prediction becomes angle 0, throttle 0 with a rate-limited warning.

Optional speed control (:class:`parts.drive.speed.SpeedControl`, PILOT_SPEED_CONTROL) replaces
the model's throttle by one that drives to its target speed (PILOT_SPEED_LIMIT); the speed key is
then appended to ``inputs``. The web page's speed limit is not a target: it caps the car's final
throttle in every mode (:class:`parts.drive.speed.SpeedLimit`).

A model trained on speeds (TRAIN_THROTTLE_LABEL = "speed": its metadata says ``throttle_label``
"speed" and ``speed_scale``) predicts a target speed, ``throttle output x speed_scale`` m/s; the
pilot then drives to it with ``target_control`` (a PI :class:`parts.drive.speed.SpeedControl`,
capped by PILOT_SPEED_LIMIT when speed control is on) and takes the measured speed as its last input.

Hot switch: :meth:`Pilot.request_model` loads another file in a background thread and swaps it in
with one reference assignment; the loop never waits for a load, and a file that fails to load, or
does not fit the car (:mod:`parts.pilots.compat`: behaviour order, undistortion), leaves the
current model driving. :class:`ModelSwitch` is the loop part that watches
``pilot/model_request`` and outputs ``pilot/model``.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from parts.pilots.backends import Backend, Runner, open_runner
from parts.pilots.compat import CarInputs, check_model

logger = logging.getLogger(__name__)

IMAGE_KEY = "cam/image_array"


class _RateLimitedLog:
    """Log a warning at most once per ``interval`` seconds, counting the ones held back."""

    def __init__(self, interval: float = 5.0) -> None:
        self.interval = interval
        self._last = -math.inf
        self._held = 0

    def warning(self, message: str, *args: Any) -> None:
        now = time.monotonic()
        if now - self._last < self.interval:
            self._held += 1
            return
        if self._held:
            message += f" ({self._held} more since the last warning)"
        self._last, self._held = now, 0
        logger.warning(message, *args)


class _Active:
    """A runner plus the state that belongs to it (frame buffer, command history): swapped as one."""

    def __init__(self, runner: Runner) -> None:
        self.runner = runner
        self.frames: deque[np.ndarray] = deque(maxlen=max(1, runner.frames))
        # Previous (angle, throttle) commands, oldest first; zeros before the first prediction, as
        # at the start of a recording (the car stands still).
        self.history: deque[tuple[float, float]] = deque(
            [(0.0, 0.0)] * runner.command_history, maxlen=max(1, runner.command_history))


class Pilot:
    """Part: a trained model driving (see the module docstring).

    Args:
        model: path of a model file (.pt), or an export (.onnx, .ts).
        backend: "auto" (a matching sibling .onnx when onnxruntime is installed, else PyTorch),
            "torch", "onnx" or "torchscript".
        speed_control: a :class:`parts.drive.speed.SpeedControl`, or None for the model's throttle.
        speed_key: memory key of the measured speed (m/s) fed to ``speed_control``.
        onnx_threads: ONNX Runtime intra-op threads (1: the loop has other parts to run).
        models_dir: folder where relative paths of :meth:`request_model` are looked up too.
        frame_shape: (height, width, 3) of the camera frames the car gives; a model trained on
            other frames, or whose input shape they do not give, is refused when it loads
            (ValueError here, ``load_error`` on a switch). None: learnt from the first frame.
        frame_hint: what to do about such a model, after the message (the settings that size this
            car's frames, or that a simulator's size is fixed).
        extra_sizes: values per extra input in this car, e.g. ``{"behavior/one_hot_state_array":
            len(BEHAVIOR_LIST)}``; a model trained with another size is refused when it loads.
        car: what the car feeds the model (BEHAVIOR_LIST, CAMERA_UNDISTORT); every model, the
            first and each hot switch, is checked against it (None: not checked).
        verify: called with each model file's path before it is read, the first and each hot
            switch; raises to refuse it (the application checks a registered model's hash so;
            this package does not know the model database).

    Raises:
        parts.pilots.compat.ModelMismatch: the model does not fit ``car``.
    """

    def __init__(self, model: str | Path, *, backend: Backend | str = "auto", speed_control: Any = None,
                 speed_key: str = "sim/speed", onnx_threads: int = 1,
                 models_dir: str | Path | None = None, frame_shape: tuple[int, ...] | None = None,
                 frame_hint: str = "give it frames of the training size or re-train",
                 extra_sizes: Mapping[str, int] | None = None, car: CarInputs | None = None,
                 target_control: Any = None, verify: Callable[[Path], None] | None = None) -> None:
        self.backend = backend
        self.target_control = target_control
        self.car = car
        self.onnx_threads = onnx_threads
        self.speed_control = speed_control
        self.speed_key = speed_key
        self.models_dir = Path(models_dir) if models_dir is not None else None
        self.frame_shape = tuple(frame_shape) if frame_shape is not None else None
        self.frame_hint = frame_hint
        self.extra_sizes = dict(extra_sizes or {})
        self.verify = verify
        if verify is not None:
            verify(Path(model))
        runner = open_runner(model, backend, onnx_threads)
        try:
            self.check_fits(runner)
        except Exception:
            runner.close()
            raise
        self._active = _Active(runner)
        self._log = _RateLimitedLog()
        self._load_lock = threading.Lock()
        self._loader: threading.Thread | None = None
        self.load_error: str | None = None  # why the last requested model was not loaded
        #: refuse hot switches to a model with other inputs (set once the part is wired in a
        #: vehicle, whose input list cannot change while it runs)
        self.lock_inputs = False
        self.nonfinite_count = 0  # predictions that were NaN or infinite
        runner = self._active.runner
        if speed_scale(runner.meta) is not None and self.target_control is None:
            from parts.drive.speed import SpeedControl

            self.target_control = SpeedControl("pi")  # the default loop period and gains
        logger.info("pilot: %s (%s, %s backend)", runner.name, runner.model_type, runner.backend)

    # -- description ----------------------------------------------------------------------------
    @property
    def runner(self) -> Runner:
        """The runner driving now."""
        return self._active.runner

    @property
    def model_name(self) -> str:
        """File name of the model driving now (``pilot/model``)."""
        return self._active.runner.name

    @property
    def meta(self) -> dict[str, Any]:
        """Metadata of the model driving now."""
        return self._active.runner.meta

    @property
    def inputs(self) -> list[str]:
        """Memory keys ``run`` takes, in order: the model's camera frames, its extra inputs, then
        (with speed control) the measured speed."""
        keys = [*self._active.runner.image_inputs, *self._active.runner.extra_inputs]
        if self._needs_speed(self._active.runner):
            keys.append(self.speed_key)
        return keys

    def _needs_speed(self, runner: Runner) -> bool:
        return self.speed_control is not None or speed_scale(runner.meta) is not None

    @property
    def INPUTS(self) -> tuple[str, ...]:  # noqa: N802 - the part declaration read by Vehicle.add
        """The part's inputs (:attr:`inputs`), as the declaration Vehicle.add reads."""
        return tuple(self.inputs)

    OUTPUTS: ClassVar[tuple[str, ...]] = ("pilot/angle", "pilot/throttle")

    @property
    def INPUT_SHAPES(self) -> dict[str, tuple[int, ...]]:  # noqa: N802 - the part declaration
        """The frames the model driving now was trained on, for the wiring check (:mod:`vehicle.shapes`)."""
        shape = self._active.runner.preprocessing.image_shape
        return {} if shape is None else {IMAGE_KEY: tuple(shape)}

    def reset(self) -> None:
        """Forget the frames and commands remembered for sequence models: a new episode starts
        (an evaluation track, a car put back on the start line). Also resets the speed controller."""
        self._active = _Active(self._active.runner)
        for control in (self.speed_control, self.target_control):
            if control is not None and callable(getattr(control, "reset", None)):
                control.reset()

    # -- the loop -------------------------------------------------------------------------------
    def run(self, image: np.ndarray | None, *rest: Any) -> tuple[float, float]:
        """``(angle, throttle)`` for the current frame(s) (and extra inputs, see :attr:`inputs`)."""
        active = self._active  # one read: a swap during this call does not mix two models
        runner = active.runner
        n_views, n_extra = len(runner.image_inputs), len(runner.extra_inputs)
        scale = speed_scale(runner.meta)
        expected = n_views + n_extra + (1 if self._needs_speed(runner) else 0)
        if len(rest) + 1 != expected:
            raise TypeError(f"Pilot.run takes {expected} inputs {self.inputs}, got {len(rest) + 1}; "
                            "wire the part with inputs=pilot.inputs")
        images, rest = (image, *rest[:n_views - 1]), rest[n_views - 1:]
        if any(view is None for view in images):  # no frame yet (camera starting): stand still, wheels
            return 0.0, 0.0  # straight, even with speed control (which would accelerate from standstill blind)
        if self.frame_shape is None and isinstance(image, np.ndarray):
            self.frame_shape = image.shape  # what a model switched to must take
            self._check_frames(runner)
        angle, throttle = self._predict(active, images, rest[:n_extra])
        if scale is not None:  # the model's target speed, driven to by the PI controller
            target = max(0.0, throttle * scale)
            limit = getattr(self.speed_control, "default_limit", None)
            throttle = self.target_control.run(None, rest[n_extra], min(target, limit) if limit else target)
            if throttle is None or not math.isfinite(throttle):
                throttle = 0.0
        elif self.speed_control is not None:
            throttle = self.speed_control.run(throttle, rest[n_extra], None)  # its own target speed
            if throttle is None or not math.isfinite(throttle):
                throttle = 0.0
            throttle = min(1.0, max(-1.0, float(throttle)))
        if runner.command_history:
            active.history.append((angle, throttle))
        return angle, throttle

    def _predict(self, active: _Active, views: tuple[np.ndarray, ...],
                 extra_values: tuple[Any, ...]) -> tuple[float, float]:
        runner = active.runner
        if len(views) > 1:  # (1, V, C, H, W): every view through the same preprocessing
            images = np.stack([runner.preprocess(view) for view in views])[None]
            return self._finish(runner, images, self._extra(active, extra_values))
        x = runner.preprocess(views[0])
        if runner.frames > 1:
            if not active.frames:  # first frame: the past is unknown, repeat it
                active.frames.extend([x] * runner.frames)
            else:
                active.frames.append(x)
            images = np.stack(active.frames)[None]
        else:
            images = x[None]
        return self._finish(runner, images, self._extra(active, extra_values))

    def _finish(self, runner: Runner, images: np.ndarray, extra: np.ndarray | None) -> tuple[float, float]:
        """The runner's prediction, clamped to [-1, 1]; a non-finite one becomes (0, 0)."""
        angle, throttle = runner.predict(images, extra)
        if not (math.isfinite(angle) and math.isfinite(throttle)):
            self.nonfinite_count += 1
            self._log.warning("pilot %s predicted a non-finite command (angle=%r, throttle=%r): "
                              "driving angle 0, throttle 0", runner.name, angle, throttle)
            return 0.0, 0.0
        return min(1.0, max(-1.0, angle)), min(1.0, max(-1.0, throttle))

    def _extra(self, active: _Active, values: tuple[Any, ...]) -> np.ndarray | None:
        runner = active.runner
        if not runner.extra_size:
            return None
        parts: list[np.ndarray] = []
        if runner.command_history:
            parts.append(np.asarray(active.history, dtype=np.float32).reshape(-1))
        for key, value in zip(runner.extra_inputs, values, strict=True):
            if value is None:
                self._log.warning("pilot input %s is None: using zeros", key)
                size = runner.extra_size - sum(p.size for p in parts)
                parts.append(np.zeros(size, dtype=np.float32))
            else:
                parts.append(np.asarray(value, dtype=np.float32).reshape(-1))
        extra = np.concatenate(parts) if len(parts) > 1 else parts[0]
        if extra.size != runner.extra_size:
            raise ValueError(f"pilot {runner.name}: extra inputs {list(runner.extra_inputs)} give "
                             f"{extra.size} values, the model was trained with {runner.extra_size} "
                             "(e.g. a different number of behaviours: check BEHAVIOR_LIST)")
        return np.ascontiguousarray(extra[None], dtype=np.float32)

    def check_fits(self, runner: Runner) -> None:
        """Raise ValueError (the message says what to change) unless ``runner``'s model takes this
        car's frames and extra inputs: checked when a model loads, so that a wrong model never
        reaches the first frame in a pilot mode."""
        if self.frame_shape is not None:
            self._check_frames(runner)
        known = [k for k in runner.extra_inputs if k in self.extra_sizes]
        if known and len(known) == len(runner.extra_inputs):
            given = 2 * runner.command_history + sum(self.extra_sizes[k] for k in known)
            if given != runner.extra_size:
                sizes = " and ".join(f"{k} has {self.extra_sizes[k]} values" for k in known)
                raise ValueError(f"{sizes} in this car, but the model was trained with {runner.extra_size} "
                                 "(a different number of behaviours? check BEHAVIOR_LIST, or re-train)")
        if self.car is not None:  # behaviour order, undistortion (ModelMismatch, a ValueError)
            check_model(runner.name, runner.meta, runner.extra_inputs, runner.extra_size, self.car)

    def _check_frames(self, runner: Runner) -> None:
        try:
            runner.check_frames(self.frame_shape)
        except ValueError as exc:  # ModelMismatch included: the same type, with what to do
            raise type(exc)(f"{exc}; {self.frame_hint}") from None

    # -- hot switch -----------------------------------------------------------------------------
    def resolve(self, path: str | Path) -> Path:
        """``path`` as given if it exists, else inside ``models_dir`` (as given, then its file name)."""
        candidate = Path(path)
        if not candidate.exists() and not candidate.is_absolute() and self.models_dir is not None:
            for inside in (self.models_dir / candidate, self.models_dir / candidate.name):
                if inside.exists():
                    return inside
        return candidate

    def request_model(self, path: str | Path) -> bool:
        """Start loading ``path`` in the background; it drives from the first loop after it loaded.

        Returns False (and does nothing) while another load is still running; the caller asks again.
        """
        with self._load_lock:
            if self._loader is not None and self._loader.is_alive():
                return False
            target = self.resolve(path)
            self._loader = threading.Thread(target=self._load, args=(target,), name="PilotModelLoader",
                                            daemon=True)
            self._loader.start()
            return True

    def _open_checked(self, path: Path) -> Runner:
        """A runner for ``path`` that fits this car and this pilot's wiring; raises (the message
        says why) otherwise. The file is read with the safe loader (no code runs)."""
        if self.verify is not None:
            self.verify(path)
        runner = open_runner(path, self.backend, self.onnx_threads)
        try:
            self.check_fits(runner)
            old = self._active.runner
            if self.lock_inputs and (runner.image_inputs, runner.extra_inputs, self._needs_speed(runner)) != \
                    (old.image_inputs, old.extra_inputs, self._needs_speed(old)):
                raise ValueError(f"the model needs inputs {[*runner.image_inputs, *runner.extra_inputs]} but the "
                                 f"pilot was wired with {[*old.image_inputs, *old.extra_inputs]}; restart the car "
                                 "with this model instead")
        except Exception:
            runner.close()
            raise
        return runner

    def check_file(self, path: str | Path) -> None:
        """Raise ValueError (or the loader's error) unless ``path`` could be switched to: the checks
        of a hot switch, without switching (a model pushed from the laptop is checked so)."""
        self._open_checked(Path(path)).close()

    def _load(self, path: Path) -> None:
        try:
            runner = self._open_checked(path)
        except Exception as exc:  # any failure keeps the current model driving
            self._refuse(path, str(exc))
            return
        old = self._active
        self._active = _Active(runner)  # the swap: one reference assignment, atomic for the loop
        self.load_error = None
        logger.info("pilot: switched from %s to %s (%s, %s backend)", old.runner.name, runner.name,
                    runner.model_type, runner.backend)
        old.runner.close()

    def _refuse(self, path: Path, why: str) -> None:
        # the loaders' own messages usually start with the path already: name it once
        self.load_error = why if why.startswith(f"{path}: ") else f"{path}: {why}"
        logger.error("pilot: cannot switch to %s, keeping %s: %s", path, self.model_name, why)

    def wait_loaded(self, timeout: float | None = None) -> bool:
        """Block until a pending load finished (for tests and scripts; the loop never calls it)."""
        loader = self._loader
        if loader is not None:
            loader.join(timeout)
            return not loader.is_alive()
        return True

    def shutdown(self) -> None:
        """Wait briefly for a pending load, then release the model."""
        self.wait_loaded(timeout=5.0)
        self._active.runner.close()


class ModelSwitch:
    """Part: watch ``pilot/model_request`` and hot-switch the pilot; outputs ``pilot/model`` and
    ``pilot/load_error`` (why the last model asked for was not loaded; None after a success).

    Runs every loop (no run_condition), so a model chosen while a human drives is loaded before
    the pilot takes over. A request equal to the last one is ignored until the request goes back
    to None (the web page hands a pick over once, so picking the same file again reloads it); a
    request made while a load is running is kept and retried on the next loops.
    """

    INPUTS: ClassVar[tuple[str, ...]] = ("pilot/model_request",)
    #: a car without the web page's model picker never asks for a switch
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("pilot/model_request",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("pilot/model", "pilot/load_error")

    def __init__(self, pilot: Pilot) -> None:
        self.pilot = pilot
        self._last: str | None = None
        self._pending: str | None = None

    def run(self, request: str | None) -> tuple[str, str | None]:
        if not request:
            self._last = None
        elif request != self._last:
            self._last = self._pending = request
        if self._pending and self.pilot.request_model(self._pending):
            self._pending = None
        return self.pilot.model_name, self.pilot.load_error


def speed_scale(meta: Mapping[str, Any]) -> float | None:
    """m/s per unit of throttle output of a model trained on speeds (TRAIN_THROTTLE_LABEL =
    "speed"); None for a model whose throttle output is a throttle."""
    training = meta.get("training") or {}
    if training.get("throttle_label") != "speed":
        return None
    return float(training["speed_scale"])
