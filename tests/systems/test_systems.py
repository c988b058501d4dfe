"""The system registry: the demo runs whatever is registered, and knows no system by name."""
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from vehest_can import systems
from vehest_can.cli import build_parser
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.systems import Setup, register, registered, unregister
from vehest_can.systems.driveline.scenario import load_driveline_scenario

PKG = Path(systems.__file__).parent.parent


def test_the_shipped_systems_are_registered():
    assert [s.name for s in registered()] == ["camber", "driveline", "roll", "tireforce"]
    for s in registered():
        assert (PKG / "systems" / s.name / "system.py").is_file()


def test_every_shipped_scenario_has_exactly_one_system():
    from vehest_can.schema import read_toml

    dirs = {s.scenario_dir() for s in registered()}
    for path in (p for d in dirs for p in d.glob("*.toml")):
        doc = read_toml(path)
        assert sum(s.claims(doc) for s in registered()) == 1, path


def test_every_scenario_file_says_its_kind_and_a_missing_one_is_named(tmp_path):
    from vehest_can.errors import ScenarioError
    from vehest_can.schema import read_toml
    from vehest_can.systems import load_any_scenario, shipped_scenarios

    for path in shipped_scenarios():
        assert "kind" in read_toml(path), path
    (tmp_path / "old.toml").write_text('kind = "chassis"\nname = "x"\nduration_s = 1.0\n')
    (tmp_path / "none.toml").write_text('name = "x"\nduration_s = 1.0\n')
    with pytest.raises(ScenarioError, match="no registered system reads kind = 'chassis'.*\"tireforce\""):
        load_any_scenario(tmp_path / "old.toml")
    with pytest.raises(ScenarioError, match='kind: missing: .*"driveline"'):
        load_any_scenario(tmp_path / "none.toml")


SYSTEM_NAMES = re.compile(r"driveline|tire|tyre|camber|chassis|skf|dkf|veh14|inspection", re.I)


def test_demo_faults_and_replay_name_no_system():
    """They loop over the registry (or ask the scenario's system), so a new system needs no edit there."""
    files = ["cli/demo.py", "cli/faults.py", "cli/replay.py", "service/replay.py",
             *(str(p.relative_to(PKG)) for p in sorted((PKG / "faults").glob("*.py")))]
    hits = [f"{f}:{i}: {line.strip()}" for f in files
            for i, line in enumerate((PKG / f).read_text().splitlines(), 1) if SYSTEM_NAMES.search(line)]
    assert not hits, "\n".join(hits)


@dataclass(frozen=True)
class ToyScenario:
    name: str
    seconds: float


class Toy:
    """A system made up here: the car is a short stretch of a driveline drive, the metric a frame count."""

    name = "toy"
    kinds = ("toy",)
    realtime = False
    faults = None
    estimators = ()  # none of its own in the ECU

    def __init__(self, folder: Path):
        self.folder = folder
        self.seen: list = []

    def driveline_scenario_dir(self) -> Path:
        return self.folder

    def claims(self, doc: dict) -> bool:
        return doc.get("kind") in self.kinds

    def load(self, path: Path):
        return ToyScenario(path.stem, 0.25)

    def car(self, scenario, duration_s=None):
        return powertrain_car(load_driveline_scenario("launch_2nd"), duration_s or scenario.seconds)

    def setup(self, scenarios: list, out: Path) -> Setup:
        return Setup()

    def metrics(self, scenario, session, out_dir: Path, setup: Setup) -> dict:
        self.seen.append(scenario.name)
        return {"scenario": scenario.name, "frames": int(len(session.frames)),
                "ids": int(len(np.unique(session.frames["id"])))}

    def tables(self, metrics: list[dict]) -> list[str]:
        return [f"toy table: {m['scenario']} {m['frames']} frames" for m in metrics]


@pytest.mark.multicast
def test_a_registered_toy_system_runs_through_the_demo(tmp_path, capsys):
    (tmp_path / "toys").mkdir()
    (tmp_path / "toys" / "toy_one.toml").write_text('kind = "toy"\n')
    toy = Toy(tmp_path / "toys")
    register(toy)
    try:
        args = build_parser().parse_args(["demo", str(tmp_path / "toys" / "toy_one.toml"), "-o", str(tmp_path / "out")])
        assert args.func(args) == 0
    finally:
        unregister(toy)
    out = capsys.readouterr().out
    assert toy.seen == ["toy_one"]
    assert "bus lockstep == in-process lockstep: identical" in out
    assert re.search(r"toy table: toy_one \d+ frames", out)
    assert (tmp_path / "out" / "toy_one" / "session.log").is_file()
