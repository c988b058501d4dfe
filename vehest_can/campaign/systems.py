"""What a campaign needs of a system: validate a scenario document, run it in process, give its
metrics as a nested dict of numbers. One adapter per scenario kind.

(Until the system registry lands these adapters name the systems; they then become each
system's registration.)"""
from __future__ import annotations

from pathlib import Path

from ..errors import ScenarioError


class Driveline:
    """Seed 001: plant + sensor node + ECU in process (lockstep), the driveline KF's metrics."""
    name = "driveline"

    @staticmethod
    def validate(doc: dict, path: Path):
        from ..scenario import scenario_from_dict
        return scenario_from_dict(doc, path)

    @classmethod
    def run(cls, doc: dict, path: Path) -> dict:
        from ..report import driveline_metrics
        from ..sim import drive_from_scenario, run_inprocess

        session = run_inprocess(drive_from_scenario(cls.validate(doc, path)))
        m = driveline_metrics(session)
        return {s["measurement_set"]: {k: v for k, v in s.items() if k != "measurement_set"} for s in m["sets"]}


class TireForce:
    """Seed 000: the 14-DOF plant and chassis sensor node, the decoded frames through every
    tyre-force variant's array API (the fixed-point one is the ECU's C, bit for bit)."""
    name = "tireforce"

    @staticmethod
    def validate(doc: dict, path: Path):
        from ..chassis import chassis_scenario_from_dict
        return chassis_scenario_from_dict(doc, path)

    @classmethod
    def run(cls, doc: dict, path: Path) -> dict:
        from .. import tfreport

        truth, _, runs = tfreport.simulate(cls.validate(doc, path))
        m = tfreport.evaluate(truth, runs)
        m.pop("acceptance", None)
        return m


def system_for(doc: dict):
    kind = doc.get("kind")
    if kind is None:
        return Driveline
    if kind == "chassis":
        return TireForce
    raise ScenarioError(f"kind: no campaign runner for scenario kind {kind!r}")


def resolve_base(name: str, here: Path) -> tuple[Path, dict]:
    """A base scenario by path (relative to the campaign file) or by a shipped scenario's name."""
    from ..chassis import chassis_scenario_dir
    from ..scenario import read_toml, scenario_dir

    candidates = [here / name, Path(name)] + [d / f"{name}.toml" for d in (scenario_dir(), chassis_scenario_dir())]
    for p in candidates:
        if p.is_file():
            return p, read_toml(p)
    raise ScenarioError(f"campaign.base: no scenario {name!r} (a path, or one of the shipped scenarios)")
