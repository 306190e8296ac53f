"""Memory keys of the path-follow parts (the contract with the driver page's top-down view)."""

from __future__ import annotations

from vehicle.keys import KeyInfo

KEYS: dict[str, KeyInfo] = {
    # -- pose (parts.path.localizer)
    "loc/x": KeyInfo("float m", "position in the path's frame (x forward at the origin pose, or east)"),
    "loc/y": KeyInfo("float m", "position in the path's frame (y left at the origin pose, or north)"),
    "loc/angle": KeyInfo("float rad", "heading, counter-clockwise, in [-pi, pi); None while unknown"),
    "loc/std": KeyInfo("float m", "1-sigma position uncertainty (grows while the GPS fix is lost)"),
    "loc/ok": KeyInfo("bool", "the pose is trustworthy (False: no fix and no fresh odometry)"),
    "loc/source": KeyInfo("str", "'odometry' | 'gps' | 'fused'"),
    # -- path (parts.path.recorder)
    "path/xy": KeyInfo("ndarray (N, 2) float32 m", "the loaded or being-recorded path; a new array on change"),
    "path/speed": KeyInfo("ndarray (N,) float32 m/s", "the speed recorded at each path point"),
    "path/version": KeyInfo("int", "increments each time path/xy changes"),
    "path/recording": KeyInfo("bool", "a path is being recorded"),
    # -- follower (parts.path.follower)
    "path/target_x": KeyInfo("float m", "pure pursuit's look-ahead point; None when not following"),
    "path/target_y": KeyInfo("float m", "pure pursuit's look-ahead point; None when not following"),
    "path/cte": KeyInfo("float m", "signed cross-track error to the path, left positive; None without a path"),
    "path/state": KeyInfo("str", "'empty' | 'recording' | 'ready' | 'following' | 'done' | 'lost'"),
    # -- commands (parts.path.buttons)
    "path/command": KeyInfo("str | None", "one-shot: 'record' (toggle), 'save', 'load', 'clear', 'reset_origin'"),
}
