"""Tyre-force scenarios: TOML files of ``kind = "tireforce"`` that drive the 14-DOF car
(:mod:`vehest_can.sim.veh14`: the plant and its chassis sensor node); the schema is in
``docs/chassis_plant.md``. Shipped ones live in ``firmware_sim/scenarios/tireforce/``."""
from __future__ import annotations

from pathlib import Path

from ...paths import ShippedSet
from ...sim.scenario import load_shipped
from ...sim.veh14 import Veh14Scenario, veh14_scenario_from_dict

KINDS = ("tireforce",)

SCENARIOS = ShippedSet("scenarios/tireforce", "firmware_sim/scenarios/tireforce")
tireforce_scenario_dir, list_tireforce_scenarios, tireforce_scenario_path = SCENARIOS.dir, SCENARIOS.names, SCENARIOS.path


def tireforce_scenario_from_dict(doc: dict, path: str | Path = "<scenario>") -> Veh14Scenario:
    """Validate an already parsed TOML document (``path`` only names it in errors)."""
    return veh14_scenario_from_dict(doc, path, KINDS[0])


def load_tireforce_scenario(path: str | Path) -> Veh14Scenario:
    """Load and validate one tyre-force scenario (a path, or the name of a shipped one)."""
    return load_shipped(SCENARIOS, path, tireforce_scenario_from_dict)


__all__ = ["KINDS", "load_tireforce_scenario", "tireforce_scenario_from_dict", "tireforce_scenario_dir",
           "tireforce_scenario_path", "list_tireforce_scenarios"]
