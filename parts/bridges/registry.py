"""The simulator family's table: SIM_TYPE (or ``--sim``) -> the part that is the simulated car,
each built by its ``from_config(cfg, **options)``: our simulator in this process, or a bridge to
an external simulator. A new simulator is a bridge module here and one row below.
"""

from __future__ import annotations

from vehicle.registry import Registry

SIMULATORS = Registry("SIM_TYPE", {
    "builtin": "parts.sim.simulator:SimCar",
    "udacity": "parts.bridges.udacity_sim:UdacitySim",
    "donkey": "parts.bridges.donkey_client:DonkeySim",
})
