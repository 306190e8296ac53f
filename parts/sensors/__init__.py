"""Sensors beyond the camera: wheel encoders and odometry, IMU, GPS and 2-D LiDAR.

Each kind is a table of types in :mod:`parts.sensors.registry` (enabled by DonkeyCar's
``HAVE_ODOM``, ``HAVE_IMU``, ``HAVE_GPS``, ``USE_LIDAR``) and a module of drivers here; their
settings live in :mod:`parts.sensors.settings`. Every sensor part writes DonkeyCar's memory keys
(``enc/*``, ``pos/*``, ``vel/*``, ``imu/*``, ``gps/*``, ``lidar/*``) and a ``<ns>/ok`` flag that
turns False when the sensor has not reported for longer than its ``max_age``; its values then read
None, so nothing downstream (the speed controller, a path follower) acts on a stale measurement.
Nothing is imported here: each driver imports its hardware library (gpiozero, pyserial, smbus2,
pynmea2) when its part starts.
"""
