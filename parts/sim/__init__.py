"""The built-in simulator: generated tracks, a kinematic car, a warped-texture camera, telemetry,
an expert driver and closed-loop evaluation (numpy + OpenCV only). See docs/simulator.md.

Modules: track (centre lines), texture (top-down images), car (bicycle model), camera (renderer),
telemetry (laps, CTE), simcar (the vehicle part), expert (pure pursuit, noise injection),
evaluate / report (closed-loop metrics, JSON, PNG), record (expert demonstrations), cli.
"""
