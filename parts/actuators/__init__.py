"""Actuators: the PCA9685 PWM driver, steering/throttle parts, and the tools around them.

- :mod:`parts.actuators.pca9685`: register-level PCA9685 driver on an smbus2 bus.
- :mod:`parts.actuators.pwm`: DonkeyCar-compatible [-1, 1] -> ticks mapping and the drivetrain part.
- :mod:`parts.actuators.esc`: throttle slew limit and the reverse double-tap state machine.
- :mod:`parts.actuators.watchdog`: the command watchdog thread.
- :mod:`parts.actuators.pwm_calibration`: the interactive ``vehicle calibrate`` session.
- :mod:`parts.actuators.config_writer`: writing found values into a car's myconfig.py.
- :mod:`parts.actuators.fake_pca9685`: the hardware-free board (DRIVE_TRAIN_TYPE = "MOCK"); the tests
  also run the real smbus2 against it (tests/fixtures/fake_i2c_dev.py).

Nothing here imports smbus2 until a real bus is opened.
"""
