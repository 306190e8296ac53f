"""Sensors beyond the camera: each kind (IMU, wheel encoders, GPS, LiDAR...) is a table of types in
:mod:`parts.sensors.registry` and a folder or module of drivers here; its settings live in a
``settings.py`` beside them. Nothing is imported here: each driver imports its hardware library
when its part starts.
"""
