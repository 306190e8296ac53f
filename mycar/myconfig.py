"""Settings of this simulated car: only what differs from the defaults (docs/config.md lists all).

Uncomment and edit a line to override a default. Loading checks every name and type: a typo is
reported with the closest valid name.
"""

# -- loop and camera
# DRIVE_LOOP_HZ = 20
# IMAGE_W = 160
# IMAGE_H = 120

# -- simulator
# SIM_TRACK_SEEDS = [1]          # tracks to drive; `vehicle sim track --seed N --png t.png` draws one
# SIM_THEME = "road"             # "road", "indoor" (taped track in a room), "park"; a list mixes them
# SIM_RANDOMIZE = None           # an integer seed: randomised light, camera, sensor, latency, distractors
# SIM_TYPE = "builtin"           # or "udacity" / "donkey": drive their simulator (docs/simulators.md)
# SIM_HOST = "127.0.0.1"         # the Donkey simulator's machine (SIM_PORT = 9091)
# DONKEY_GYM_ENV_NAME = "donkey-generated-track-v0"

# -- driving with a pilot
# AI_THROTTLE_MULT = 1.0
# DEFAULT_MODEL_TYPE = "linear"

# -- web page
# WEB_CONTROL_PORT = 8887
