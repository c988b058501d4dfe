"""Driveline scenarios: TOML files of ``kind = "driveline"`` that drive the powertrain car
(:mod:`vehest_can.sim.powertrain`: the plant and its sensor node DLS); the schema is in
``docs/scenarios.md``. Shipped ones live in ``firmware_sim/scenarios/driveline/``."""
from __future__ import annotations

from ...sim.powertrain import powertrain_scenario_from_dict
from ...sim.scenario import Kind

KIND = Kind("driveline", powertrain_scenario_from_dict)
KINDS = (KIND.kind,)
_SHIPPED = KIND.shipped
driveline_scenario_dir, list_driveline_scenarios, driveline_scenario_path = _SHIPPED.dir, _SHIPPED.names, _SHIPPED.path
driveline_scenario_from_dict, load_driveline_scenario = KIND.from_dict, KIND.load

__all__ = ["KIND", "KINDS", "load_driveline_scenario", "driveline_scenario_from_dict", "driveline_scenario_dir",
           "driveline_scenario_path", "list_driveline_scenarios"]
