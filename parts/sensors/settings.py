"""Settings of the sensor family: car geometry, wheel encoders and odometry, IMU, GPS and LiDAR
(each kind's type setting picks a row of :mod:`parts.sensors.registry`).

Declared as the config loader reads them (see :mod:`vehicle.config`): ``NAME: type = value``, the
comment lines above a setting document it, ``# == Title ==`` starts a section of docs/config.md.
Names and defaults follow DonkeyCar's cfg_complete.py / cfg_path_follow.py where it has them.
"""

from __future__ import annotations

from typing import Annotated, Literal

from parts.sensors.registry import ENCODERS, GPSES, IMUS, LIDARS
from vehicle.config_checks import Range

# == Car geometry ==

# Distance between the front and rear axles, metres (DonkeyCar's WHEEL_BASE): the bicycle model of
# odometry turns by distance x tan(wheel angle) / WHEEL_BASE.
WHEEL_BASE: Annotated[float, Range(0.02, 5, unit="m")] = 0.26
# Distance between the left and right wheels, metres (AXLE_LENGTH): the unicycle model of a
# differential drive turns by (right - left distance) / AXLE_LENGTH.
AXLE_LENGTH: Annotated[float, Range(0.02, 5, unit="m")] = 0.2
# Radius of the driven wheels, metres (WHEEL_RADIUS); with ENCODER_PPR it gives MM_PER_TICK.
WHEEL_RADIUS: Annotated[float, Range(0.005, 1, unit="m")] = 0.0315
# Front wheel angle at full steering (angle -1 = full left), radians (MAX_STEERING_ANGLE).
# Measure it: turn the wheels fully and read the angle, or drive a full-lock circle of radius R:
# MAX_STEERING_ANGLE = atan(WHEEL_BASE / R).
MAX_STEERING_ANGLE: Annotated[float, Range(0.01, 1.5, unit="rad")] = 0.436

# == Wheel encoders and odometry ==

# A wheel encoder is fitted (DonkeyCar's HAVE_ODOM): the odometer writes enc/distance, enc/speed
# (the speed limit's measured speed) and the pose pos/x, pos/y, pos/angle. In the built-in
# simulator the simulated car's encoder is used instead, with the same settings.
HAVE_ODOM: bool = False
# A second encoder on the other wheel of a differential drive (HAVE_ODOM_2): the first is the
# left wheel, this the right; the pose then follows the unicycle model with AXLE_LENGTH.
HAVE_ODOM_2: bool = False
# How the ticks reach the car: "GPIO" (an encoder on the Pi's header pins, ODOM_PIN) or "ARDUINO"
# (a microcontroller running DonkeyCar's encoder sketch on ODOM_SERIAL).
ENCODER_TYPE: Annotated[str, ENCODERS.choice()] = "GPIO"
# Encoder pulses per revolution of the wheel (ENCODER_PPR).
ENCODER_PPR: Annotated[int, Range(1, 100_000)] = 20
# Ignore pulses closer than this after the previous one, nanoseconds (noisy encoders).
ENCODER_DEBOUNCE_NS: Annotated[int, Range(0, 1_000_000_000, unit="ns")] = 0
# Direction of a single-channel encoder's ticks: "FORWARD_ONLY", "FORWARD_REVERSE" (sign of the
# last non-zero throttle) or "FORWARD_REVERSE_STOP" (no counting at zero throttle); DonkeyCar's
# constants 1, 2, 3 are accepted. A quadrature encoder (ODOM_PIN_B) knows its direction.
TACHOMETER_MODE: Literal["FORWARD_ONLY", "FORWARD_REVERSE", "FORWARD_REVERSE_STOP", 1, 2, 3] = "FORWARD_REVERSE"
# Travel per tick in millimetres (MM_PER_TICK). Calibrate it: roll the car 1 m and divide 1000
# by the ticks counted (`vehicle hw check` prints them).
MM_PER_TICK: Annotated[float, Range(0.001, 10_000, lo_open=True, unit="mm")] = \
    WHEEL_RADIUS * 2 * 3.141592653589793 * 1000 / ENCODER_PPR
# GPIO header pin of the encoder (its A channel): a board pin number (13, DonkeyCar's numbering),
# "GPIO27" (BCM) or a DonkeyCar pin specifier "RPI_GPIO.BCM.27".
ODOM_PIN: Annotated[int | str, Range(1, 40, note="a header pin number, or a pin name")] = 13
# B channel of a quadrature encoder (None: a single-channel encoder on ODOM_PIN).
ODOM_PIN_B: Annotated[int | str | None, Range(1, 40, note="None: single channel")] = None
# GPIO pin of the second (right) encoder with HAVE_ODOM_2.
ODOM_PIN_2: Annotated[int | str, Range(1, 40, note="a header pin number, or a pin name")] = 14
# Serial port of the encoder microcontroller (ENCODER_TYPE "ARDUINO").
ODOM_SERIAL: str = "/dev/ttyACM0"
# Baud rate of ODOM_SERIAL (DonkeyCar's sketches use 115200).
ODOM_SERIAL_BAUDRATE: Annotated[int, Range(1200, 4_000_000, unit="baud")] = 115200
# Readings over which enc/speed is averaged (ODOM_SMOOTHING): 1 = from the last two readings.
ODOM_SMOOTHING: Annotated[int, Range(1, 100)] = 1
# No encoder reading for this long: enc/ok False, enc/speed None (the speed limit stops the car).
ODOM_MAX_AGE_S: Annotated[float, Range(0.05, 10, unit="s")] = 0.5

# == IMU ==

# An IMU is fitted (HAVE_IMU): imu/acl_x..z (m/s^2) and imu/gyr_x..z (rad/s) are recorded.
HAVE_IMU: bool = False
# The chip family: "mpu6050" or "mpu9250" (DonkeyCar's names); either reads any register-compatible
# chip (WHO_AM_I 0x68 MPU-6050, 0x70 MPU-6500, 0x71 MPU-9250, 0x73 MPU-9255), named in the log at start.
IMU_SENSOR: Annotated[str, IMUS.choice()] = "mpu6050"
# I2C address: 0x68, or 0x69 with the AD0 pin high (IMU_ADDRESS).
IMU_ADDRESS: Annotated[int, Range(0x08, 0x77)] = 0x68
# I2C bus of the IMU (None = 1, the header's pins 3/5).
IMU_I2C_BUSNUM: Annotated[int | None, Range(0, 255)] = None
# Digital low-pass filter 0-6 (IMU_DLP_CONFIG): 0 = 260 Hz bandwidth ... 6 = 5 Hz.
IMU_DLP_CONFIG: Annotated[int, Range(0, 6)] = 0
# Accelerometer full scale, ±g.
IMU_ACCEL_RANGE: Literal[2, 4, 8, 16] = 2
# Gyroscope full scale, ±degrees per second.
IMU_GYRO_RANGE: Literal[250, 500, 1000, 2000] = 250
# No IMU reading for this long: imu/ok False, its values None.
IMU_MAX_AGE_S: Annotated[float, Range(0.05, 10, unit="s")] = 0.5

# == GPS ==

# A GPS receiver is fitted (HAVE_GPS): gps/x, gps/y in metres in a local frame, gps/ok.
HAVE_GPS: bool = False
# The receiver's protocol: "NMEA" (NMEA 0183 sentences GGA/RMC over serial, any talker GP/GN/GL).
GPS_TYPE: Annotated[str, GPSES.choice()] = "NMEA"
# Serial port of the receiver (GPS_SERIAL), e.g. "/dev/ttyAMA1" or "/dev/ttyUSB0".
GPS_SERIAL: str = "/dev/ttyUSB0"
# Baud rate of GPS_SERIAL (receivers ship at 9600 or 38400; DonkeyCar's default is 115200).
GPS_SERIAL_BAUDRATE: Annotated[int, Range(1200, 4_000_000, unit="baud")] = 115200
# (latitude, longitude) in degrees of the local frame's origin; None = the first fix of each run.
# Set it to keep a recorded path valid between runs.
GPS_ORIGIN: Annotated[tuple[float, float] | None, Range(-180, 180, unit="degrees", note="None: the first fix")] = None
# Append every NMEA sentence with its time to this file (GPS_NMEA_PATH), None = off.
GPS_NMEA_PATH: str | None = None
# No valid fix for this long: gps/ok False, its values None. A lost fix is stale at once.
GPS_MAX_AGE_S: Annotated[float, Range(0.1, 60, unit="s")] = 2.0

# == LiDAR and obstacle stop ==

# A 2-D LiDAR is fitted (USE_LIDAR): lidar/dist_array, the nearest return per angle bin (metres,
# bins counter-clockwise from straight ahead, 0.0 = no return, -1.0 = no fresh reading: unknown).
USE_LIDAR: bool = False
# The LiDAR: "RP" (Slamtec RPLidar A1/A2/A3 and compatible scan protocol).
LIDAR_TYPE: Annotated[str, LIDARS.choice()] = "RP"
# Serial port of the LiDAR.
LIDAR_SERIAL: str = "/dev/ttyUSB0"
# Baud rate: 115200 (A1, A2), 256000 (A3).
LIDAR_SERIAL_BAUDRATE: Annotated[int, Range(1200, 4_000_000, unit="baud")] = 115200
# Angle bins of lidar/dist_array over the full turn.
LIDAR_BINS: Annotated[int, Range(4, 3600)] = 360
# The LiDAR's own angle, degrees clockwise, that points to the car's front (0 for an RPLidar
# mounted with its cable/motor side to the rear; 180 when mounted the other way round).
LIDAR_ANGLE_OFFSET: Annotated[float, Range(0, 360, hi_open=True, unit="degrees")] = 0.0
# Returns farther than this are ignored, metres.
LIDAR_MAX_RANGE: Annotated[float, Range(0.1, 100, unit="m")] = 12.0
# No full turn for this long: lidar/ok False, the array None.
LIDAR_MAX_AGE_S: Annotated[float, Range(0.1, 10, unit="s")] = 0.5
# Two consecutive scan nodes farther apart than this leave the bins between them unread (unknown
# once their last reading is LIDAR_MAX_AGE_S old), a node farther than this after the previous one
# is taken for line noise, and a turn needs 360 / LIDAR_MAX_GAP nodes to be published. An RPLidar
# A1/A2 reads a node every 0.5-2 degrees.
LIDAR_MAX_GAP: Annotated[float, Range(0.5, 90, unit="degrees")] = 5.0
