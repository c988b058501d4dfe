"""--car on the verbs: replay runs the ECU calibrated for the car (a log recorded with another car's
calibration replays DIFFERENT), a bad car file is an error line naming the key (no traceback), a car
file on a plant it does not describe is refused, a campaign may vary the car."""
import pytest

from vehest_can.bus import lockstep
from vehest_can.bus.frames import TICK_S
from vehest_can.bus.log import SessionLog
from vehest_can.carfile import car_spec, load_car, paper_car
from vehest_can.cli import main
from vehest_can.schema import read_toml
from vehest_can.service.replay import ECU_TX
from vehest_can.sim.session import run_inprocess
from vehest_can.sim.veh14 import Veh14Car
from vehest_can.systems.ecu import Ecu, EcuConfig
from vehest_can.systems.tireforce.scenario import tireforce_scenario_from_dict, tireforce_scenario_path


def short_doc(**top) -> dict:
    doc = read_toml(tireforce_scenario_path("chassis_paper_mu_drop"))
    doc.update({"duration_s": 0.4, **top})
    return doc


def write_lockstep_log(session, path) -> None:
    """The session as a lockstep log: RESET, then per tick the car's frames, SIM_Sync, the ECU's."""
    msgs = list(session.messages())
    out, i = [lockstep.sync_message(lockstep.RESET_TICK_BASE, lockstep.RESET)], 0
    for k in range(len(session.truth)):
        while i < len(msgs) and session.frame_tick[i] == k and msgs[i].arbitration_id not in ECU_TX:
            out.append(msgs[i])
            i += 1
        sync = lockstep.sync_message(k)
        sync.timestamp = k * TICK_S
        out.append(sync)
        while i < len(msgs) and session.frame_tick[i] == k:
            out.append(msgs[i])
            i += 1
    with SessionLog(path, {"SIM", "CHS"}, epoch=1764620000.0) as log:
        for m in out:
            log.on_message_received(m)


@pytest.fixture(scope="module")
def commonroad_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("car") / "cr2.log"
    sc = tireforce_scenario_from_dict(short_doc(car="commonroad_vehicle2"), path.with_suffix(".toml"))
    write_lockstep_log(run_inprocess(Veh14Car(sc), Ecu(EcuConfig(car=sc.car))), path)
    return path


def test_replay_with_the_car_is_identical_without_it_different(commonroad_log, capsys):
    assert main(["replay", str(commonroad_log), "--car", "commonroad_vehicle2"]) == 0
    assert "identical: all" in capsys.readouterr().out
    assert main(["replay", str(commonroad_log)]) == 3  # the paper's calibration: another estimator
    assert "DIFFERENT" in capsys.readouterr().out
    # the car as a file, by path
    assert main(["replay", str(commonroad_log), "--car", str(paper_car().path)]) == 3


def test_a_bad_car_is_an_error_line_naming_the_key(tmp_path, capsys, commonroad_log):
    bad = tmp_path / "bad.toml"
    bad.write_text(paper_car().path.read_text().replace("half_track_rear_m = 0.760", 'half_track_rear_m = "wide"'))
    for argv in (["replay", str(commonroad_log)], ["daemon", "--duration", "0.1"], ["sim", "chassis_paper_mu_drop"],
                 ["demo", "chassis_paper_mu_drop", "-o", str(tmp_path / "o")], ["campaign", "tireforce_small"]):
        assert main([*argv, "--car", str(bad)]) == 1, argv
        err = capsys.readouterr().err
        assert err.startswith(f"error: {bad}: half_track_rear_m: 'wide' is a string, not a number") and \
            "Traceback" not in err, (argv, err)
    assert main(["replay", str(commonroad_log), "--car", "commonroad_vehicle4"]) == 1
    assert "no multi-body data" in capsys.readouterr().err


def test_a_car_file_is_the_14dof_cars_only(capsys):
    assert main(["sim", "launch_2nd", "--car", "paper"]) == 1
    assert "a car file is the 14-DOF car's" in capsys.readouterr().err
    assert main(["campaign", "driveline_small", "--car", "paper"]) == 1
    assert "a car file is the 14-DOF car's" in capsys.readouterr().err


def test_a_campaign_varies_the_car(tmp_path, capsys):
    import tomli_w

    from vehest_can.campaign import Store, load_campaign

    (tmp_path / "cars").mkdir()
    (tmp_path / "cars" / "mine.toml").write_text(paper_car().path.read_text().replace('name = "paper"', 'name = "mine"'))
    (tmp_path / "base.toml").write_text(tomli_w.dumps(short_doc(name="base", duration_s=1.5)))
    spec = tmp_path / "c.toml"
    spec.write_text('[campaign]\nname = "cars"\nbase = "base.toml"\nruns = 3\n'
                    'metrics = ["variants.skfmec-fixed.rms_pct.FL"]\n'
                    '[[vary]]\nkey = "car"\ndist = "grid"\nvalues = ["paper", "commonroad_vehicle2", "cars/mine.toml"]\n'
                    '[[vary]]\nkey = "seed"\ndist = "list"\nvalues = [7]\n')  # one noise for every run
    c = load_campaign(spec)
    cars = [c.run_doc(i)[0]["car"] for i in range(3)]
    assert cars == ["paper", "commonroad_vehicle2", car_spec(load_car(tmp_path / "cars" / "mine.toml"))]
    assert main(["campaign", str(spec), "-o", str(tmp_path / "out"), "-j", "1", "--no-plots"]) == 0
    table = Store(tmp_path / "out", c).table().to_pylist()
    fl = {r["run"]: r["metric.variants.skfmec-fixed.rms_pct.FL"] for r in table}
    assert len(fl) == 3 and fl[0] == fl[2] != fl[1]  # mine.toml is the paper's car, CommonRoad's another
    bad = tmp_path / "bad.toml"
    bad.write_text(spec.read_text().replace('"cars/mine.toml"', '"cars/none.toml"'))
    with pytest.raises(Exception, match=r"vary\[0\].values\[2\]: car 'cars/none.toml': neither"):
        load_campaign(bad)
