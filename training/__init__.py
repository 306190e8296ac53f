"""Training pilots: the library the application's ``train`` command and trainer console use.

No part imports this package (tests/vehicle/test_layers.py checks it): what runs on the car lives
in :mod:`parts.pilots`. Its settings are declared in :mod:`training.settings`.
"""
