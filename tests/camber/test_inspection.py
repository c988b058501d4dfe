"""Camber inspection through the ECU and the CLI: calibrate from logs, publish only at rest."""
import json
from dataclasses import replace

import can
import pytest

from vehest_can.cli import main
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.sim.session import run_inprocess
from vehest_can.systems.camber import inspection
from vehest_can.systems.camber.api import WHEELS, load_calibrations, load_into_ecu
from vehest_can.systems.camber.scenario import load_camber_scenario
from vehest_can.systems.ecu import Ecu

SC = load_camber_scenario("camber_inspection")
TRUTH = {w: SC.camber.theta_deg[i] for i, w in enumerate(WHEELS)}


def write_log(session, path):
    with can.Logger(str(path)) as writer:
        for m in session.messages():
            writer.on_message_received(m)
    return path


@pytest.fixture(scope="module")
def cal_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("cal")
    logs = {}
    for pose in ("x_down", "z_down"):
        s = run_inprocess(powertrain_car(replace(SC, camber=replace(SC.camber, pose=pose)), duration_s=4.0), Ecu())
        logs[pose] = write_log(s, d / f"{pose}.log")
    out = d / "cal.json"
    assert main(["camber", "calibrate", "--x-down", str(logs["x_down"]), "--z-down", str(logs["z_down"]),
                 "-o", str(out)]) == 0
    return out


def ecu_with(cal_file):
    ecu = Ecu()
    load_into_ecu(ecu, load_calibrations(cal_file))
    return ecu


def test_calibrated_camber_is_within_the_eq22_bound_on_every_wheel(cal_file):
    s = run_inprocess(powertrain_car(SC), ecu_with(cal_file))
    res = inspection.ecu_results(s.messages())
    for w in WHEELS:
        assert res[w]["reason"] == "OK"
        assert abs(res[w]["camber_deg"] - TRUTH[w]) <= res[w]["bound_deg"]
        assert res[w]["misalign_deg"] == pytest.approx(SC.camber.psi_deg[WHEELS.index(w)], abs=0.2)


def test_uncalibrated_chip_misalignment_shows_outside_the_bound(cal_file):
    from vehest_can.systems.camber.api import Calibration

    ecu = Ecu()
    load_into_ecu(ecu, {w: Calibration.identity() for w in WHEELS})
    res = inspection.ecu_results(run_inprocess(powertrain_car(SC), ecu).messages())
    assert max(abs(res[w]["camber_deg"] - TRUTH[w]) for w in WHEELS) > 1.0
    assert any(abs(res[w]["camber_deg"] - TRUTH[w]) > res[w]["bound_deg"] for w in WHEELS)


def test_no_calibration_says_so():
    res = inspection.ecu_results(run_inprocess(powertrain_car(SC), Ecu()).messages())
    assert {r["reason"] for r in res.values()} == {"NOT_CALIBRATED"}


def test_refused_while_the_car_moves(cal_file):
    moving = replace(SC, gear=2, throttle=((0.0, 0.3),))  # in gear with throttle: rolling
    res = inspection.ecu_results(run_inprocess(powertrain_car(moving), ecu_with(cal_file)).messages())
    assert {r["reason"] for r in res.values()} <= {"NOT_STATIONARY", "MOVING", "MAGNITUDE"}
    assert all(r["reason"] != "OK" for r in res.values())


def test_measure_verb_prints_the_ecus_results(cal_file, tmp_path, capsys):
    log = write_log(run_inprocess(powertrain_car(SC), ecu_with(cal_file)), tmp_path / "s.log")
    assert main(["camber", "measure", "--log", str(log), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert set(res) == set(WHEELS) and all(r["reason"] == "OK" for r in res.values())
    assert main(["camber", "measure", "--log", str(log)]) == 0
    assert "FL" in capsys.readouterr().out


def test_bad_captures_are_rejected_with_the_reason(tmp_path, capsys):
    x = write_log(run_inprocess(powertrain_car(replace(SC, camber=replace(SC.camber, pose="x_down")),
                                                    duration_s=2.0), Ecu()), tmp_path / "x.log")
    # the same pose twice: the two axes are parallel, not orthogonal
    assert main(["camber", "calibrate", "--x-down", str(x), "--z-down", str(x), "-o", str(tmp_path / "c.json")]) == 1
    assert "orthogonal" in capsys.readouterr().err
    # too short a capture
    short = write_log(run_inprocess(powertrain_car(replace(SC, camber=replace(SC.camber, pose="z_down")),
                                                        duration_s=0.3), Ecu()), tmp_path / "short.log")
    assert main(["camber", "calibrate", "--x-down", str(x), "--z-down", str(short), "-o", str(tmp_path / "c.json")]) == 1
    assert "samples" in capsys.readouterr().err
    assert not (tmp_path / "c.json").exists()


def test_bad_calibration_file_stops_the_daemon_with_a_clear_error(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"format": "vehest-can/camber-calibration", "version": 99, "wheels": {}}))
    assert main(["daemon", "-i", "virtual", "-c", "x", "--camber-cal", str(bad), "--duration", "0.1"]) == 1
    assert "unsupported version 99" in capsys.readouterr().err


def test_paper_minimum_bound():
    assert inspection.min_worst_case_deg(4.0) == pytest.approx(0.2292, abs=5e-4)
