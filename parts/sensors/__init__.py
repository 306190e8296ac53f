"""Sensors of a real car: wheel encoders and odometry, IMU, GPS and 2-D LiDAR.

Every sensor part writes DonkeyCar's memory keys (``enc/*``, ``pos/*``, ``vel/*``, ``imu/*``,
``gps/*``, ``lidar/*``) and a ``<ns>/ok`` flag that turns False when the sensor has not reported
for longer than its ``max_age``; its values then read None, so nothing downstream (the speed
controller, a path follower) acts on a stale measurement. Hardware libraries (gpiozero, pyserial,
smbus2, pynmea2) are imported only when a part opens its device.
"""
