"""A campaign's runs through the registered systems (:mod:`vehest_can.systems`): the system that
claims the base scenario validates each run's document and runs it (its ``campaign`` runner);
with faults, a system that has a fault study runs through the injectors and the wire model."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import ScenarioError
from ..schema import read_toml
from ..systems import CampaignRunner, System, claiming, registered, unclaimed


def system_for(doc: dict) -> System:
    system = claiming(doc)
    if system is None:
        raise ScenarioError(unclaimed(doc))
    _runner(system)
    return system


def takes_faults(system: System) -> bool:
    return system.faults is not None


def _runner(system: System) -> CampaignRunner:
    runner = getattr(system, "campaign", None)
    if runner is None:
        raise ScenarioError(f"the {system.name} system takes no campaigns (it has no campaign runner)")
    return runner


def validate(system: System, doc: dict, path: Path):
    return _runner(system).from_dict(doc, path)


def run(system: System, doc: dict, path: Path, faults: tuple[str, ...] | None, seed: int) -> dict:
    scenario = validate(system, doc, path)
    if faults is None:
        return _runner(system).run(scenario)
    return _fault_metrics(system, scenario, faults, seed)


def _fault_metrics(system: System, scenario, faults: tuple[str, ...], seed: int) -> dict:
    """What the ECU made of a faulty bus, by the system's fault study: per filter the RMS error
    against the truth while it said valid, the valid fraction and the ticks per health state;
    the RX fault counters at the end."""
    from ..bus.frames import TICK_S
    from ..faults.campaign import run_with_faults
    from ..faults.spec import faults_from_cli
    from ..systems.ecu import COUNTERS

    study = system.faults
    if study is None:
        raise ScenarioError(f"the {system.name} system's runs take no faults (it has no fault study)")
    r = run_with_faults(system.car(scenario), faults_from_cli(list(faults), seed=seed % 2**32), study=study)
    after = np.arange(r.n) * TICK_S >= 0.5  # the filters' start-up, as the reports skip it
    out: dict = {}
    for which in study.filters:
        ok = r.valid(which) & after
        err = r.estimate(which)[ok] - r.truth[ok]
        health = np.bincount(r.health(which)[after].astype(np.int64), minlength=4)
        out[which] = {"rms_est_minus_truth": float(np.sqrt(np.mean(err ** 2))) if ok.any() else float("nan"),
                      "valid_fraction": float(ok.sum() / max(int(after.sum()), 1)),
                      "health": dict(zip(("INIT", "OK", "DEGRADED", "FAULT"), map(int, health)))}
    out["counters"] = {c: int(r.counter(c)[-1]) for c in COUNTERS}
    return out


def resolve_base(name: str, here: Path) -> tuple[Path, dict]:
    """A base scenario by path (relative to the campaign file) or by a shipped scenario's name."""
    dirs = list(dict.fromkeys(s.scenario_dir() for s in registered()))
    for p in [here / name, Path(name)] + [d / f"{name}.toml" for d in dirs]:
        if p.is_file():
            return p, read_toml(p)
    names = sorted({p.stem for d in dirs for p in d.glob("*.toml")})
    raise ScenarioError(f"campaign.base: no scenario {name!r}: give a path (relative to the campaign file), or "
                        f"the name of a shipped scenario: {', '.join(names)}")
