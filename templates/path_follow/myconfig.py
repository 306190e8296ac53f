"""Settings of this path-follow car: only what differs from the defaults (docs/config.md lists all).

Uncomment and edit a line to override a default. Loading checks every name and type: a typo is
reported with the closest valid name. docs/path_follow.md explains the workflow and the tuning.
"""

# -- sensors on the car: the localiser needs an encoder (odometry), a GPS, or both (fused);
#    `manage.py drive --sim` switches on the simulated ones it needs
# HAVE_ODOM = True               # wheel encoder
# HAVE_GPS = True                # NMEA receiver on GPS_SERIAL
# MM_PER_TICK = 9.9              # roll 1 m, divide 1000 by the ticks counted
# GPS_ORIGIN = (48.1351, 11.5820)   # keeps a GPS path valid between runs

# -- path follow
# PATH_LOCALIZER = "odometry"    # "gps" or "fused"
# PATH_FILENAME = "donkey_path.csv"
# PATH_MIN_DIST = 0.2            # metres between recorded points
# PATH_LOOK_AHEAD_DIST = 0.5     # pure pursuit's look-ahead, metres (0: PID only, as DonkeyCar)
# PID_P = 0.5                    # steering per metre off the path
# PID_D = 0.2
# PATH_SPEED_SCALE = 1.0         # follow at this share of the recorded speed
# PATH_MAX_SPEED = 1.5           # m/s cap
# USE_CONSTANT_THROTTLE = True   # drive at PID_THROTTLE instead
# LOC_ODOM_DRIFT = 0.02          # odometry's error per metre driven (the simulator uses 0.005: no slip)

# -- drivetrain (real car; `vehicle calibrate` finds these)
# DRIVE_TRAIN_TYPE = "PWM_STEERING_THROTTLE"   # "MOCK" on the bench
# STEERING_LEFT_PWM = 460
# STEERING_RIGHT_PWM = 290
# THROTTLE_FORWARD_PWM = 500
# THROTTLE_STOPPED_PWM = 370

# -- controllers and buttons
# CONTROLLER_TYPE = "ps4"
# USE_JOYSTICK_AS_DEFAULT = True
# TOGGLE_RECORDING_BTN = "circle"
# SAVE_PATH_BTN = "square"
# LOAD_PATH_BTN = "dpad_left"
# ERASE_PATH_BTN = "dpad_down"
# RESET_ORIGIN_BTN = "dpad_up"
