"""Path follow: record a route by driving it, then follow it (DonkeyCar's path_follow template).

- :mod:`parts.path.pathfile`: a path (x, y, speed per point) and its CSV file.
- :mod:`parts.path.geometry`: nearest point, cross-track error, look-ahead point, pure pursuit.
- :mod:`parts.path.localizer`: the pose the path is recorded and followed in (odometry, GPS, fused).
- :mod:`parts.path.recorder`: the path part: record, save, load, clear, reset origin.
- :mod:`parts.path.follower`: pure pursuit plus a PID on the cross-track error -> pilot/angle,
  pilot/throttle (so every safety path of a learned pilot applies).
- :mod:`parts.path.buttons`: gamepad buttons and the web page's buttons -> ``path/command``.
"""
