"""What a pilot model sees in a recording, frame by frame: the saliency overlay and its steering.

:class:`SalientView` is the ``view`` of :func:`parts.tub.visualize.write_movie` (``vehicle tub movie
--model M [--salient]``): it feeds the model the recording as the car would (the behaviour one-hot
of each record, the previous recorded commands of a ``memory`` model, the last frames of a sequence
model) and returns the frame with the saliency of the steering laid over it (the lane image's
beside it for the lanes models) and the model's steering.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np

from parts.pilots.saliency import METHODS, Explainer


class SalientView:
    """Per record: (picture, model steering). ``method`` None draws no map, only the steering."""

    def __init__(self, explainer: Explainer, method: str | None = "integrated", samples: int = 16) -> None:
        model = explainer.model
        if model.views > 1:
            raise ValueError(f"a tub movie films one camera; model type {model.type_name!r} takes "
                             f"{model.views} views: explain it with parts.pilots.saliency.Explainer")
        if method is not None and method not in METHODS:
            raise ValueError(f"saliency method must be one of {METHODS}, got {method!r}")
        self.explainer, self.method, self.samples = explainer, method, samples
        self._frames: deque[np.ndarray] = deque(maxlen=model.frames)
        self._commands: deque[tuple[float, float]] = deque([(0.0, 0.0)] * model.command_history,
                                                           maxlen=model.command_history or None)

    def _extra(self, rec: Any) -> list[float] | None:
        model = self.explainer.model
        if model.command_history:
            return [v for pair in self._commands for v in pair]
        if model.extra_inputs:
            value = rec.get(model.extra_inputs[0])
            return list(value) if isinstance(value, list | tuple) and len(value) == model.extra_size else None
        return None

    def __call__(self, frame: np.ndarray, rec: Any) -> tuple[np.ndarray, float | None]:
        """The picture to film for ``frame`` (RGB uint8) and the model's steering on it."""
        self._frames.append(frame)
        frames = list(self._frames)
        frames = [frames[0]] * (self._frames.maxlen - len(frames)) + frames  # a sequence's start: repeated
        extra = self._extra(rec)
        if self.method is None:
            angle, _ = self.explainer.predict(frames, extra)
            picture = frame
        else:
            sal = self.explainer.explain(frames, extra, method=self.method, samples=self.samples)
            angle = sal.prediction[0]
            pictures = self.explainer.overlays(frames, sal)
            picture = pictures["camera"]
            if "lanes" in pictures:  # the lane image the model saw, beside the camera, same height
                import cv2

                lane = pictures["lanes"]
                width = max(1, round(lane.shape[1] * frame.shape[0] / lane.shape[0]))
                picture = np.concatenate([picture, cv2.resize(lane, (width, frame.shape[0]),
                                                              interpolation=cv2.INTER_NEAREST)], axis=1)
        if self.explainer.model.command_history:
            a, t = rec.angle, rec.throttle
            self._commands.append((float(a or 0.0), float(t or 0.0)))
        return picture, angle
