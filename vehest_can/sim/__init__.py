"""Simulation: the scenario schema (``scenario``: the TOML reader every file kind uses), the car and the
three ways to drive it against the ECU (``session``), and what a session gives people (``report``)."""

#: the plants a car with a choice can be played by (a scenario's ``plant`` key): ours, and CommonRoad's
#: multi-body model (vehest_can.sim.mbplant)
PLANTS = ("veh14", "commonroad_mb")

#: the car's corners in the order of every per-wheel quantity (C arrays, DBC signals, tables): the
#: paper's 1..4 in a left turn
WHEELS = ("FL", "FR", "RL", "RR")
