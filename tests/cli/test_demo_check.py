"""`demo --check` exits non-zero when an acceptance line fails; `--junit` writes them for CI; the
terminal says PASS/FAIL with a legend. A system made up here, whose acceptance lines are decided
by the session it gets over the bus."""
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from vehest_can.bus.frames import frame_id
from vehest_can.bus.log import read_log
from vehest_can.cli import build_parser
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.sim.report import LEGEND, verdict_word
from vehest_can.systems import Setup
from vehest_can.systems.driveline.scenario import load_driveline_scenario


class Gate:
    name = "gate"
    kinds = ("gate",)
    realtime = False
    faults = None

    def __init__(self, folder: Path, min_frames: int):
        self.folder, self.min_frames = folder, min_frames

    def driveline_scenario_dir(self):
        return self.folder

    def claims(self, doc):
        return doc.get("kind") == "gate"

    def load(self, path):
        return type("Sc", (), {"name": path.stem})()

    def car(self, scenario, duration_s=None):
        return powertrain_car(load_driveline_scenario("launch_2nd"), duration_s or 0.25)

    def setup(self, scenarios, out):
        return Setup()

    def metrics(self, scenario, session, out_dir, setup):
        n = int(len(session.frames))
        ids = int(len(np.unique(session.frames["id"])))
        return {"scenario": scenario.name, "acceptance": [
            {"line": "some frames", "verdict": "pass" if n > 0 else "SHORT", "detail": f"{n} frames"},
            {"line": f">= {self.min_frames} frames", "verdict": "pass" if n >= self.min_frames else "SHORT",
             "detail": f"{n} frames, {ids} IDs"}]}

    def tables(self, metrics):
        return []


def demo(tmp_path, min_frames, *flags):
    (tmp_path / "g").mkdir(exist_ok=True)
    (tmp_path / "g" / "one.toml").write_text('kind = "gate"\n')
    gate = Gate(tmp_path / "g", min_frames)
    args = build_parser().parse_args(["demo", str(tmp_path / "g" / "one.toml"), "-o", str(tmp_path / "out"), *flags])
    return args.func(args, systems=[gate])


@pytest.mark.multicast
def test_check_fails_on_a_failed_line_and_junit_says_which(tmp_path, capsys):
    assert demo(tmp_path, 10**9) == 0                       # without --check: the report only
    out = capsys.readouterr().out
    assert "  PASS  gate.one: some frames" in out and "  FAIL  gate.one: >= 1000000000 frames" in out
    assert LEGEND in out and "SHORT" not in out.split("acceptance:")[-1]
    junit = tmp_path / "report.xml"
    assert demo(tmp_path, 10**9, "--check", "--junit", str(junit)) == 4
    assert "1 acceptance line(s) FAIL" in capsys.readouterr().err
    root = ET.parse(junit).getroot()
    assert root.tag == "testsuites" and root.get("tests") == "3" and root.get("failures") == "1"
    (suite,) = root.findall("testsuite")
    cases = {c.get("name"): c for c in suite.findall("testcase")}
    assert set(cases) == {"bus lockstep == in-process lockstep", "some frames", ">= 1000000000 frames"}
    assert cases[">= 1000000000 frames"].find("failure") is not None
    assert "frames" in cases[">= 1000000000 frames"].find("failure").get("message")
    assert cases["some frames"].find("failure") is None


@pytest.mark.multicast
def test_check_passes_when_every_line_passes(tmp_path, capsys):
    assert demo(tmp_path, 1, "--check", "--log-format", "asc", "--log-per-bus") == 0
    assert "3 PASS, 0 FAIL" in capsys.readouterr().out
    # the session logs as asked: ASC, one per bus (this car has only powertrain frames)
    pt = read_log(tmp_path / "out" / "one" / "session-pt.asc")
    assert pt and {m.channel for m in pt} == {0} and any(not m.is_rx for m in pt)
    # ... and on the chassis bus only the ECU's SecOC sync frame (1 Hz, one per bus; the demo has SecOC on)
    assert {m.arbitration_id for m in read_log(tmp_path / "out" / "one" / "session-ch.asc")} == {
        frame_id("VEHEST_SecOCSyncCh", "ch")}


def test_verdict_words():
    assert [verdict_word(v) for v in ("pass", "PASS", "ok", True, "SHORT", "fail", False, None)] == \
        ["PASS"] * 4 + ["FAIL"] * 4


class Killer(Gate):
    """The gate system, whose first scenario's metrics kill the demo's ECU daemon (as a crash would)."""

    def metrics(self, scenario, session, out_dir, setup):
        import os
        import signal

        m = super().metrics(scenario, session, out_dir, setup)
        if scenario.name == "one":
            for stat in Path("/proc").glob("[0-9]*/stat"):
                try:
                    fields = stat.read_text().rsplit(")", 1)[1].split()
                    cmd = (stat.parent / "cmdline").read_bytes()
                except OSError:
                    continue
                if int(fields[1]) == os.getpid() and b"daemon" in cmd:
                    os.kill(int(stat.parent.name), signal.SIGKILL)
        return m


@pytest.mark.multicast
def test_a_daemon_that_dies_half_way_is_named_and_the_finished_scenarios_are_kept(tmp_path, capsys):
    import json

    (tmp_path / "g").mkdir()
    for name in ("one", "two"):
        (tmp_path / "g" / f"{name}.toml").write_text('kind = "gate"\n')
    gate = Killer(tmp_path / "g", 1)
    out = tmp_path / "out"
    args = build_parser().parse_args(["demo", str(tmp_path / "g" / "one.toml"), str(tmp_path / "g" / "two.toml"),
                                      "-o", str(out)])
    rc = args.func(args, systems=[gate])
    cap = capsys.readouterr()
    assert rc == 1
    assert "demo: stopped after 1 of 2 scenarios: lockstep: " in cap.err
    assert "the ECU daemon exited (status -9)" in cap.err
    assert "gate.one: some frames" in cap.out and "gate.two" not in cap.out  # the summary of what finished
    assert [m["scenario"] for m in json.loads((out / "metrics.json").read_text())] == ["one"]
    assert (out / "one" / "table.txt").exists() and (out / "ecu_daemon.log").exists()
