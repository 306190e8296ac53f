"""Vision for a real or simulated camera (thesis seed 002, chapters 6 and 7).

- :mod:`parts.vision.calibration`: chessboard views -> camera matrix and lens distortion, saved in
  the car folder; :class:`~parts.vision.calibration.ChessboardCollector` gathers views live.
- :mod:`parts.vision.undistort`: the ``Undistort`` part (one precomputed remap per frame).
- :mod:`parts.vision.lanes`: bird's-eye warp + HLS S-channel threshold (+ optional white/yellow
  mask) -> binary lane image; the ``LaneExtraction`` part and the preprocessing step of the
  two-stream ``lanes`` pilot.

Nothing here needs the simulator: every part takes frames from any camera part.
"""
