"""The built-in simulator: generated tracks in visual themes, a kinematic car, a warped-texture
camera, domain randomisation, telemetry and an expert driver (numpy + OpenCV only). See
docs/simulator.md.

Modules: track (centre lines), themes (what a theme looks like: data), surfaces (ground materials),
backdrops (walls, tree lines), texture (top-down images), randomize (per-episode conditions),
scenery (backdrop, distractors and the car's shadow over the ground), world (a track drawn in a
theme, cached), camera (renderer), sensor (per-frame image effects), kinematics (bicycle model),
telemetry (laps, CTE), simulator (the SimCar part), expert (pure pursuit, noise injection),
episode (the parts of an evaluation episode: reset when off the road, give up without frames),
eval_report (tables, JSON, PNG).
"""
