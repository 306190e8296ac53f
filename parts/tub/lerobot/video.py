"""Camera videos of a LeRobot dataset, written and read with PyAV.

LeRobot encodes each camera as MP4 (libsvtav1, yuv420p, a keyframe every 2 frames, crf 30,
preset 12 in lerobot 0.5) at the dataset's fps, frame k of a file at time k / fps, and puts the
episodes of a file one after the other: an episode's frames span ``[from_timestamp, to_timestamp)``
of its file, and frame ``frame_index`` is shown at ``from_timestamp + frame_index / fps``. LeRobot
encodes each episode on its own and joins the files; here the frames of consecutive episodes go
into one encoder, which gives the same times without re-reading files. A new file is started at
an episode boundary once the current one holds ``VIDEO_FILES_SIZE_IN_MB``.
"""

from __future__ import annotations

import contextlib
import fractions
import logging
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from parts.tub.lerobot.format import (
    CHUNKS_SIZE,
    VIDEO_FILES_SIZE_IN_MB,
    VIDEO_PATH,
    LeRobotFormatError,
    av,
    chunk_file_path,
    next_file,
)

logger = logging.getLogger(__name__)

CODECS = ("libsvtav1", "h264", "hevc")
DEFAULT_CODEC = "libsvtav1"
DEFAULT_CRF = 30
CRF_MAX = {"libsvtav1": 63, "h264": 51, "hevc": 51}  # the encoders' own ranges (x264/x265: 0..51)
EVEN_SIZE = ("h264", "hevc")  # yuv420p halves the chroma planes: x264 and x265 refuse odd sizes
GOP = 2                 # LeRobot's g: a keyframe every 2 frames makes random access cheap
SVTAV1_PRESET = 12      # LeRobot's default preset for libsvtav1 (fast)
PIX_FMT = "yuv420p"


def check_codec(codec: str, crf: int) -> None:
    """LeRobotFormatError unless ``codec`` is one LeRobot uses and ``crf`` is within its range."""
    if codec not in CODECS:
        raise LeRobotFormatError(f"video codec {codec!r} is not one LeRobot uses; choose one of {', '.join(CODECS)}")
    if isinstance(crf, bool) or not isinstance(crf, int) or not 0 <= crf <= CRF_MAX[codec]:
        raise LeRobotFormatError(f"crf must be within 0..{CRF_MAX[codec]} for {codec}, got {crf!r} "
                                 "(lower = better quality, bigger files; LeRobot uses 30)")


def codec_options(codec: str, crf: int) -> dict[str, str]:
    """The encoder options LeRobot's VideoEncoderConfig gives this codec."""
    check_codec(codec, crf)
    opts = {"g": str(GOP), "crf": str(crf)}
    if codec == "libsvtav1":
        opts["preset"] = str(SVTAV1_PRESET)
    return opts


class VideoFiles:
    """The video files of one camera feature: frames appended in order, episode by episode.

    A file is closed at an episode boundary once the encoder has written ``max_mb`` MiB into it
    (counted from the packets: the muxer buffers, so the file's size on disk lags behind).
    A failure of the encoder is a LeRobotFormatError naming codec and frame size.
    """

    def __init__(self, root: Path, video_key: str, fps: int, width: int, height: int, *,
                 codec: str = DEFAULT_CODEC, crf: int = DEFAULT_CRF,
                 max_mb: float = VIDEO_FILES_SIZE_IN_MB, chunks_size: int = CHUNKS_SIZE) -> None:
        self._av = av()
        if codec not in self._av.codecs_available:
            raise LeRobotFormatError(f"this PyAV build cannot encode {codec}; choose another --vcodec "
                                     f"({', '.join(c for c in CODECS if c in self._av.codecs_available)})")
        if codec in EVEN_SIZE and (width % 2 or height % 2):
            raise LeRobotFormatError(f"{codec}: {width}x{height} frames: h264 and hevc need an even width and "
                                     "height; use --vcodec libsvtav1 (LeRobot's default, any size)")
        self.root = root
        self.key = video_key
        self.fps = fps
        self.width, self.height = width, height
        self.codec = codec
        self.crf = crf
        self.options = codec_options(codec, crf)
        self.max_mb = max_mb
        self.chunks_size = chunks_size
        self.chunk, self.file = 0, 0
        self._container: Any = None
        self._stream: Any = None
        self._path: Path | None = None
        self.frames_in_file = 0
        self.bytes_in_file = 0
        self.first_file: Path | None = None

    def _failed(self, exc: Exception) -> LeRobotFormatError:
        why = " ".join(str(exc).split())
        return LeRobotFormatError(f"{self._path}: video encoder {self.codec} failed on {self.width}x{self.height} "
                                  f"frames ({why}); change the codec or quality (--vcodec, --crf), or export "
                                  "the frames as images (--images)")

    def start_episode(self) -> tuple[int, int, float]:
        """Begin an episode: (chunk, file, from_timestamp) where its frames will be."""
        if self._container is not None and self.bytes_in_file / (1024 ** 2) >= self.max_mb:
            self._close()
            self.chunk, self.file = next_file(self.chunk, self.file, self.chunks_size)
        if self._container is None:
            self._open()
        return self.chunk, self.file, self.frames_in_file / self.fps

    def _open(self) -> None:
        # SVT-AV1 prints its banner and settings to stderr unless told to report errors only
        os.environ.setdefault("SVT_LOG", "1")
        self._path = self.root / chunk_file_path(VIDEO_PATH, self.chunk, self.file, video_key=self.key)
        self._path.parent.mkdir(parents=True, exist_ok=True)
        try:
            # faststart: the index goes before the frames (as LeRobot's files), so players and the
            # Hub's viewer can start without reading the whole file
            self._container = self._av.open(str(self._path), "w", options={"movflags": "faststart"})
            stream = self._container.add_stream(self.codec, rate=self.fps, options=self.options)
            stream.pix_fmt = PIX_FMT
            stream.width, stream.height = self.width, self.height
            stream.codec_context.time_base = fractions.Fraction(1, self.fps)
        except self._av.FFmpegError as exc:
            if self._container is not None:
                with contextlib.suppress(self._av.FFmpegError):
                    self._container.close()
                self._container = None
            raise self._failed(exc) from exc
        self._stream = stream
        self.frames_in_file = 0
        self.bytes_in_file = 0
        if self.first_file is None:
            self.first_file = self._path

    def _mux(self, frame: Any) -> None:
        """Encode ``frame`` (None: flush) and write the packets that come out."""
        try:
            with scheduling_kept():
                for packet in self._stream.encode(frame):
                    self.bytes_in_file += packet.size
                    self._container.mux(packet)
        except self._av.FFmpegError as exc:  # the codec opens on the first frame: most failures show here
            raise self._failed(exc) from exc

    def add(self, frame: np.ndarray) -> None:
        """Encode the next frame (HxWx3 uint8 RGB) of the current episode."""
        vf = self._av.VideoFrame.from_ndarray(np.ascontiguousarray(frame), format="rgb24")
        vf.pts = self.frames_in_file
        vf.time_base = fractions.Fraction(1, self.fps)
        self._mux(vf)
        self.frames_in_file += 1

    def end_episode(self) -> float:
        """The to_timestamp of the episode just added."""
        return self.frames_in_file / self.fps

    def _close(self) -> None:
        if self._container is None:
            return
        try:
            self._mux(None)
        finally:
            container, self._container, self._stream = self._container, None, None
            try:
                container.close()
            except self._av.FFmpegError as exc:
                raise self._failed(exc) from exc

    def close(self) -> None:
        """Flush the encoder and close the current file."""
        self._close()

    def feature_info(self) -> dict[str, Any]:
        """The ``info`` of the feature in info.json, read from the first file as LeRobot does."""
        if self.first_file is None:
            return {}
        return probe(self.first_file, extra={"video.g": GOP, "video.crf": self.crf,
                                             **({"video.preset": SVTAV1_PRESET} if self.codec == "libsvtav1" else {})})


@contextlib.contextmanager
def scheduling_kept() -> Iterator[None]:
    """Give the calling thread back its scheduling policy if the encoder changed it: SVT-AV1, run as
    root, raises the thread that starts an encoder to real time (SCHED_FIFO 99) and leaves it so;
    every thread and process started from it afterwards would inherit that, and a busy one would
    take a core from everything else (a car's loop included). Lowering a priority needs no rights."""
    if not hasattr(os, "sched_getscheduler"):  # not on macOS or Windows, nor is SVT-AV1's habit
        yield
        return
    policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
    try:
        yield
    finally:
        if (os.sched_getscheduler(0), os.sched_getparam(0)) != (policy, param):
            os.sched_setscheduler(0, policy, param)


def probe(path: Path, extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """LeRobot's ``get_video_info``: size, codec, pixel format, fps, channels, audio of a video."""
    mod = av()
    with mod.open(str(path)) as container:
        stream = container.streams.video[0]
        channels = 1 if "gray" in stream.pix_fmt else 4 if ("rgba" in stream.pix_fmt or "yuva" in stream.pix_fmt) else 3
        info: dict[str, Any] = {
            "video.height": stream.height, "video.width": stream.width,
            "video.codec": stream.codec_context.codec.canonical_name if stream.codec_context.codec else stream.name,
            "video.pix_fmt": stream.pix_fmt, "video.is_depth_map": False,
            "video.fps": int(stream.base_rate) if stream.base_rate else None,
            "video.channels": channels,
            "has_audio": bool(container.streams.audio),
        }
    info.update(extra or {})
    return info


class FrameReader:
    """Frames of a camera's video files by time, for reading a dataset in order.

    Decodes forward from where the last frame was found; a time earlier than that, or another
    file, reopens and seeks. ``tolerance`` (seconds) is how far a frame's time may be from the one
    asked for (LeRobot uses 1e-4 s).
    """

    def __init__(self, tolerance: float = 1e-4) -> None:
        self._av = av()
        self.tolerance = tolerance
        self._path: Path | None = None
        self._container: Any = None
        self._frames: Any = None
        self._pending: Any = None  # a decoded frame not used yet
        self._last_time = -1.0

    def frame(self, path: Path, t: float) -> np.ndarray:
        """The RGB frame of ``path`` shown at ``t`` seconds."""
        if path != self._path or t < self._last_time - self.tolerance:
            self._open(path, t)
        while True:
            try:
                frame = self._pending if self._pending is not None else next(self._frames, None)
            except self._av.FFmpegError as exc:
                raise LeRobotFormatError(f"{path}: cannot be decoded near {t:.4f} s: {exc}") from exc
            self._pending = None
            if frame is None:
                raise LeRobotFormatError(f"{path}: no frame at {t:.4f} s (the video ends before; "
                                         "its episodes' from/to timestamps do not match it)")
            ft = float(frame.time)
            if ft < t - self.tolerance:
                continue
            if ft > t + self.tolerance:
                self._pending = frame
                raise LeRobotFormatError(f"{path}: no frame at {t:.4f} s (the nearest is at {ft:.4f} s): the "
                                         "data's timestamps do not match the video")
            self._last_time = ft
            return frame.to_ndarray(format="rgb24")

    def _open(self, path: Path, t: float) -> None:
        self.close()
        if not path.is_file():
            raise LeRobotFormatError(f"{path}: video file missing")
        try:
            self._container = self._av.open(str(path))
        except self._av.FFmpegError as exc:
            raise LeRobotFormatError(f"{path}: cannot be read as a video: {exc}") from exc
        stream = self._container.streams.video[0]
        stream.thread_type = "AUTO"
        if t > 0 and stream.time_base:
            self._container.seek(int(t / stream.time_base), stream=stream, backward=True)
        self._frames = self._container.decode(stream)
        self._path = path
        self._last_time = -1.0

    def close(self) -> None:
        if self._container is not None:
            self._container.close()
        self._container = self._frames = self._pending = self._path = None
