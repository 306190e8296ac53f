"""Memory keys of the sensors: odometry, IMU, GPS and LiDAR (DonkeyCar's names).

Collected with every family's ``keys.py`` into :data:`vehicle.keys.STANDARD_KEYS` (see
:mod:`vehicle.keys`).
"""

from __future__ import annotations

from vehicle.keys import KeyInfo

KEYS: dict[str, KeyInfo] = {
    # -- speed and odometry (DonkeyCar's names)
    "enc/speed": KeyInfo("float, m/s", "measured speed (encoder odometer, VESC RPM or simulator); None when stale"),
    "enc/ticks": KeyInfo("int", "cumulative signed wheel-encoder ticks"),
    "enc/left/ticks": KeyInfo("int", "cumulative ticks of the left wheel's encoder (differential drive)"),
    "enc/right/ticks": KeyInfo("int", "cumulative ticks of the right wheel's encoder (differential drive)"),
    "enc/timestamp": KeyInfo("float, s", "time of the encoder reading, on the vehicle's clock"),
    "enc/distance": KeyInfo("float, m", "signed distance driven since start (odometer)"),
    "enc/left/distance": KeyInfo("float, m", "distance driven by the left wheel"),
    "enc/right/distance": KeyInfo("float, m", "distance driven by the right wheel"),
    "enc/ok": KeyInfo("bool", "False while the encoder has not reported within its max age"),
    "pos/x": KeyInfo("float, m", "odometry pose: x in the start frame"),
    "pos/y": KeyInfo("float, m", "odometry pose: y in the start frame (left of the start heading)"),
    "pos/angle": KeyInfo("float, rad", "odometry heading, counter-clockwise, in [-pi, pi)"),
    "vel/x": KeyInfo("float, m/s", "odometry velocity along x"),
    "vel/y": KeyInfo("float, m/s", "odometry velocity along y"),
    "vel/angle": KeyInfo("float, rad/s", "odometry turn rate, counter-clockwise"),
    # -- IMU (x forward, y left, z up as mounted)
    "imu/acl_x": KeyInfo("float, m/s^2", "IMU acceleration along x"),
    "imu/acl_y": KeyInfo("float, m/s^2", "IMU acceleration along y"),
    "imu/acl_z": KeyInfo("float, m/s^2", "IMU acceleration along z (+9.8 at rest, upright)"),
    "imu/gyr_x": KeyInfo("float, rad/s", "IMU rotation rate about x"),
    "imu/gyr_y": KeyInfo("float, rad/s", "IMU rotation rate about y"),
    "imu/gyr_z": KeyInfo("float, rad/s", "IMU rotation rate about z (counter-clockwise seen from above)"),
    "imu/ok": KeyInfo("bool", "False while the IMU has not reported within its max age"),
    # -- GPS (local metric frame: x east, y north, origin at the first fix or GPS_ORIGIN)
    "gps/x": KeyInfo("float, m", "GPS position east of the local origin; None without a fix"),
    "gps/y": KeyInfo("float, m", "GPS position north of the local origin; None without a fix"),
    "gps/latitude": KeyInfo("float, degrees", "GPS latitude"),
    "gps/longitude": KeyInfo("float, degrees", "GPS longitude"),
    "gps/accuracy": KeyInfo("float, m", "horizontal accuracy estimate (HDOP x 5 m)"),
    "gps/speed": KeyInfo("float, m/s", "speed over ground (NMEA RMC)"),
    "gps/ok": KeyInfo("bool", "a valid, fresh fix"),
    # -- LiDAR
    "lidar/dist_array": KeyInfo("list[float], m", "nearest return per angle bin, bins counter-clockwise from straight "
                                                  "ahead, 0.0 = no return, -1.0 = unknown (no fresh reading)"),
    "lidar/ok": KeyInfo("bool", "False while the LiDAR has not completed a turn within its max age"),
    # -- battery (a part of the user's that measures it: the web page, the console and telemetry show it)
    "battery/voltage": KeyInfo("float, V", "the drive battery's voltage"),
}
