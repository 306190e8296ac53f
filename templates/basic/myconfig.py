"""Settings of this car: only what differs from the defaults (see docs/config.md for all of them).

Uncomment and edit a line to override a default. Loading checks every name and type: a typo is
reported with the closest valid name. `vehicle calibrate --channel N --save` writes the PWM
values found on your car into this file.
"""

# -- loop and camera
# DRIVE_LOOP_HZ = 20
# CAMERA_TYPE = "PICAM"          # PICAM, CVCAM, CSIC, VIDEO, IMAGE_LIST or MOCK (no hardware)
# IMAGE_W = 160
# IMAGE_H = 120

# -- drivetrain (PCA9685): run `vehicle calibrate` to find these
# DRIVE_TRAIN_TYPE = "PWM_STEERING_THROTTLE"   # "MOCK" on the bench; H-bridges, VESC, MM1: docs/drivetrains.md
# STEERING_CHANNEL = 1
# THROTTLE_CHANNEL = 0
# STEERING_LEFT_PWM = 460
# STEERING_RIGHT_PWM = 290
# THROTTLE_FORWARD_PWM = 500
# THROTTLE_STOPPED_PWM = 370
# THROTTLE_REVERSE_PWM = 220

# -- sensors (docs/sensors.md; check them with `vehicle hw check`)
# HAVE_ODOM = True               # wheel encoder: enc/speed for the speed limit, pose pos/x, pos/y
# ENCODER_TYPE = "GPIO"          # or "ARDUINO" (DonkeyCar's encoder sketch on ODOM_SERIAL)
# ODOM_PIN = 13                  # header pin; ODOM_PIN_B = 15 for a quadrature encoder
# MM_PER_TICK = 9.9              # roll 1 m, divide 1000 by the ticks counted
# HAVE_IMU = True                # MPU6050 / MPU9250 on I2C (IMU_SENSOR, IMU_ADDRESS)
# HAVE_GPS = True                # NMEA receiver on GPS_SERIAL
# USE_LIDAR = True               # RPLidar on LIDAR_SERIAL; OBSTACLE_STOP = True brakes before obstacles

# -- controllers
# CONTROLLER_TYPE = "ps4"        # ps3, ps4, xbox, f710, generic or custom (see `vehicle createjs`)
# USE_JOYSTICK_AS_DEFAULT = False

# -- driving with a pilot
# AI_THROTTLE_MULT = 1.0
# DEFAULT_MODEL_TYPE = "linear"
