"""Simulation: the scenario schema (``scenario``: the TOML reader every file kind uses), the car and the
three ways to drive it against the ECU (``session``), and what a session gives people (``report``)."""

#: the plants a car with a choice can be played by (a scenario's ``plant`` key): ours, and CommonRoad's
#: multi-body model (vehest_can.sim.mbplant)
PLANTS = ("veh14", "commonroad_mb")
