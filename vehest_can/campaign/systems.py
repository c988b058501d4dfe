"""What a campaign needs of a system: validate a scenario document, run it in process, give its
metrics as a nested dict of numbers. One adapter per scenario kind.

(Until the system registry lands these adapters name the systems; they then become each
system's registration.)"""
from __future__ import annotations

from pathlib import Path

from ..errors import ScenarioError


class Driveline:
    """Seed 001: plant + sensor node + ECU in process (lockstep), the driveline KF's metrics.
    With faults (the ``faults`` catalogue's CLI syntax), the same run through the fault injectors
    and the wire model (:func:`vehest_can.faults.run_with_faults`)."""
    name = "driveline"
    takes_faults = True

    @staticmethod
    def validate(doc: dict, path: Path):
        from ..scenario import scenario_from_dict
        return scenario_from_dict(doc, path)

    @classmethod
    def run(cls, doc: dict, path: Path, faults: tuple[str, ...] | None = None) -> dict:
        from ..sim import drive_from_scenario

        drive = drive_from_scenario(cls.validate(doc, path))
        if faults is not None:
            return _fault_metrics(drive, faults, int(doc["seed"]))
        from ..report import driveline_metrics
        from ..sim import run_inprocess

        m = driveline_metrics(run_inprocess(drive))
        return {s["measurement_set"]: {k: v for k, v in s.items() if k != "measurement_set"} for s in m["sets"]}


def _fault_metrics(drive, faults: tuple[str, ...], seed: int) -> dict:
    """What the ECU made of a faulty bus: per filter the RMS error against the truth while it said
    valid, the valid fraction, ticks per health state; the RX fault counters at the end."""
    import numpy as np

    from ..faults import faults_from_cli, run_with_faults
    from ..frames import TICK_S
    from ..report import SETTLE_S

    run = run_with_faults(drive, faults_from_cli(list(faults), seed=seed % 2**32))
    after = np.arange(run.n) * TICK_S >= SETTLE_S
    out: dict = {}
    for which, name in (("T", "speeds+torque"), ("S", "speeds")):
        ok = run.valid(which) & after
        err = run.shaft_torque(which)[ok] - run.truth_to[ok]
        health = np.bincount(run.health(which)[after], minlength=4)
        out[name] = {"rms_est_minus_truth_nm": float(np.sqrt(np.mean(err ** 2))) if ok.any() else float("nan"),
                     "valid_fraction": float(ok.sum() / max(after.sum(), 1)),
                     "health": dict(zip(("INIT", "OK", "DEGRADED", "FAULT"), map(int, health)))}
    from ..ecu import COUNTERS
    out["counters"] = {c: int(run.counter(c)[-1]) for c in COUNTERS}
    return out


class TireForce:
    """Seed 000: the 14-DOF plant and chassis sensor node, the decoded frames through every
    tyre-force variant's array API (the fixed-point one is the ECU's C, bit for bit)."""
    name = "tireforce"
    takes_faults = False  # the fault injectors know the powertrain bus only

    @staticmethod
    def validate(doc: dict, path: Path):
        from ..chassis import chassis_scenario_from_dict
        return chassis_scenario_from_dict(doc, path)

    @classmethod
    def run(cls, doc: dict, path: Path, faults=None) -> dict:
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
