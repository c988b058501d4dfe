"""Driveline scenarios: TOML files of ``kind = "driveline"`` that drive the powertrain car
(:mod:`vehest_can.sim.powertrain`: the plant and its sensor node DLS); the schema is in
``docs/scenarios.md``. Shipped ones live in ``firmware_sim/scenarios/driveline/``."""
from __future__ import annotations

from pathlib import Path

from ...paths import ShippedSet
from ...sim.powertrain import PowertrainScenario, powertrain_scenario_from_dict
from ...sim.scenario import load_shipped

KINDS = ("driveline",)

SCENARIOS = ShippedSet("scenarios/driveline", "firmware_sim/scenarios/driveline")
driveline_scenario_dir, list_driveline_scenarios, driveline_scenario_path = SCENARIOS.dir, SCENARIOS.names, SCENARIOS.path


def driveline_scenario_from_dict(doc: dict, path: str | Path = "<scenario>") -> PowertrainScenario:
    """Validate an already parsed TOML document (``path`` only names it in errors)."""
    return powertrain_scenario_from_dict(doc, path, KINDS[0])


def load_driveline_scenario(path: str | Path) -> PowertrainScenario:
    """Load and validate one driveline scenario (a path, or the name of a shipped one)."""
    return load_shipped(SCENARIOS, path, driveline_scenario_from_dict)


__all__ = ["KINDS", "load_driveline_scenario", "driveline_scenario_from_dict", "driveline_scenario_dir",
           "driveline_scenario_path", "list_driveline_scenarios"]
