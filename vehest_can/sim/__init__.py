"""Simulation: the scenario schema (``scenario``: the TOML reader every file kind uses), the car and the
three ways to drive it against the ECU (``session``), and what a session gives people (``report``)."""
