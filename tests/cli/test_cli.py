"""The console script: demo end to end on a short scenario, and clear errors for bad input."""
import json
import random
import time
from pathlib import Path

import pytest

from vehest_can.bus.frames import frame_id, sent_by
from vehest_can.bus.log import read_log
from vehest_can.cli import main


def short_scenario(tmp_path, text_extra=""):
    p = tmp_path / "short.toml"
    p.write_text(f"""
kind = "driveline"
name = "short"
description = "1.5 s launch for the CLI test"
duration_s = 1.5
seed = 3
[driver]
gear = 2
throttle = [[0.0, 0.0], [0.3, 0.0], [0.8, 0.5]]
{text_extra}
""")
    return p


@pytest.mark.multicast
def test_demo_end_to_end(tmp_path, capsys):
    out = tmp_path / "out"
    port = random.randint(49152, 64999)  # a bus of the test's own
    assert main(["demo", str(short_scenario(tmp_path)), "-o", str(out), "-i", "udp_multicast",
                 "-c", "239.74.163.2", "--bus-kwargs", f"port={port}"]) == 0
    text = capsys.readouterr().out
    assert "bus lockstep == in-process lockstep: identical" in text
    # the driveline table as expected (the run is seeded and in lockstep: the same figures on every machine)
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("scenario        set"))
    expected = (Path(__file__).parent / "expected" / "demo_short_driveline.txt").read_text().splitlines()
    assert lines[start:start + len(expected)] == expected
    for name in ("torque.png", "error.png", "gain.png", "session.log"):
        assert (out / "short" / name).stat().st_size > 1000
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics[0]["bus_equals_inprocess"] is True
    assert {s["measurement_set"] for s in metrics[0]["sets"]} == {"speeds+torque", "speeds"}
    # the session log is the ECU's: its frames Tx, the car's Rx, absolute time, the pt channel
    msgs = read_log(out / "short" / "session.log")
    ecu = sent_by({"VEHEST"})
    assert msgs and all(m.is_rx == (m.arbitration_id not in ecu) for m in msgs)
    sync_ch = frame_id("VEHEST_SecOCSyncCh", "ch")  # SecOC's sync frame: the ECU sends one on each bus
    assert any(not m.is_rx for m in msgs) and {m.channel for m in msgs if m.arbitration_id != sync_ch} == {"pt"}
    assert abs(msgs[0].timestamp - time.time()) < 600
    assert msgs[-1].timestamp - msgs[0].timestamp == pytest.approx(1.5, abs=0.01)


@pytest.mark.multicast
def test_demo_chassis_scenario_end_to_end(tmp_path, capsys):
    """A chassis scenario (seed 000) through the daemon: fixed-point estimates from the bus equal
    the array API's, the report tabulates all three estimators and draws Fig. 3-6."""
    src = Path(__file__).parents[2] / "firmware_sim" / "scenarios" / "tireforce" / "chassis_paper_mu_drop.toml"
    sc = tmp_path / "chassis_short.toml"
    sc.write_text(src.read_text().replace("duration_s = 10.0", "duration_s = 1.0")
                  .replace('name = "chassis_paper_mu_drop"', 'name = "chassis_short"'))
    out = tmp_path / "out"
    port = random.randint(49152, 64999)
    assert main(["demo", str(sc), "-o", str(out), "-i", "udp_multicast", "-c", "239.74.163.3",
                 "--bus-kwargs", f"port={port}"]) == 0
    text = capsys.readouterr().out
    assert "bus lockstep == in-process lockstep: identical" in text
    assert "array API on the decoded samples: identical" in text
    assert "skfmec-fixed" in text and "ekf" in text and "acceptance:" in text
    for name in ("fig3_zeta.png", "fig4_share.png", "fig5_inner_front.png", "fig6_outer_front.png", "session.log"):
        assert (out / "chassis_short" / name).stat().st_size > 1000
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics[0]["bus_equals_inprocess"] is True and metrics[0]["ecu_equals_array_api"] is True


def test_bad_scenario_file_names_the_key(tmp_path, capsys):
    bad = short_scenario(tmp_path, "[road]\nroughness_std_nm = -3\n")
    assert main(["demo", str(bad), "-o", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error:") and "road.roughness_std_nm" in err


def test_missing_files_are_errors_not_tracebacks(tmp_path, capsys):
    assert main(["replay", str(tmp_path / "nope.log")]) == 1
    assert "no such log file" in capsys.readouterr().err
    for argv in (["replay", str(tmp_path)], ["replay", "--play", str(tmp_path)]):
        assert main(argv) == 1
        assert "is a folder, not a log file" in capsys.readouterr().err
    garbage = tmp_path / "garbage.log"
    garbage.write_text("this is not a candump log\n")
    assert main(["replay", str(garbage)]) == 1
    assert "error:" in capsys.readouterr().err


def test_bad_daemon_burst_limit_is_an_error(capsys):
    assert main(["daemon", "--rx-burst-limit", "300"]) == 1
    assert "error: --rx-burst-limit must be a finite number of frames per message and tick in 0..255, not 300" \
        in capsys.readouterr().err


@pytest.mark.parametrize("target", ["qemu", "qemu-m7"])
def test_an_emulated_ecu_runs_in_lockstep_only(capsys, target):
    """Both emulated cores refuse a wall clock, in the daemon and in the demo, before anything starts."""
    assert main(["daemon", "--target", target, "--mode", "realtime"]) == 1
    assert f"error: --target {target} needs --mode lockstep" in capsys.readouterr().err
    assert main(["demo", "--target", target, "--realtime", "5"]) == 1
    assert f"--realtime with --target {target}: the emulated ECU runs in lockstep only" in capsys.readouterr().err


FLOATS = ("nan", "inf", "-inf", "-1", "0", "1e300")
RANGES = [  # (verb and flags, the flag, its range and unit in the error, values out of it)
    (["camber", "bound"], "--lsb-mg", "mg in 0.0001..500", (*FLOATS, "1e-300", "501")),
    (["camber", "measure", "--from-log", "x.log"], "--timeout", "seconds > 0 and at most 3600", (*FLOATS, "3601")),
    (["camber", "calibrate", "-o", "cal.json", "--x-down", "x.log", "--z-down", "z.log"], "--timeout",
     "seconds > 0 and at most 3600", FLOATS),
    (["camber", "calibrate", "-o", "cal.json", "--x-down", "x.log", "--z-down", "z.log"], "--samples",
     "samples per pose in 2..1000000", ("1", "-5", "1000001")),
    (["replay", "x.log"], "--max-gap", "seconds in 0.0005..3600", (*FLOATS, "1e-300", "0.0004", "3601")),
    (["daemon"], "--rx-burst-limit", "frames per message and tick in 0..255", ("-1", "256")),
    (["faults"], "--tx-queue", "frames in 1..10000", ("0", "10001")),
]


@pytest.mark.parametrize("argv, flag, bound, values", RANGES, ids=[f"{r[0][0]}{r[1]}" for r in RANGES])
def test_physical_arguments_out_of_range_are_errors(tmp_path, monkeypatch, capsys, argv, flag, bound, values):
    """Once `camber bound --lsb-mg 1e-300` printed 0.0000 deg: every such flag has its physical range,
    checked before any file is read or bus opened."""
    monkeypatch.chdir(tmp_path)
    for value in values:
        assert main([*argv, f"{flag}={value}"]) == 1, value
        err = capsys.readouterr().err
        assert err.startswith(f"error: {flag} must be a finite number of {bound}") and "Traceback" not in err, err
        assert err.count("\n") == 1


def test_camber_bound_prints_its_figure_with_four_significant_digits(capsys):
    assert main(["camber", "bound", "--lsb-mg", "4"]) == 0
    assert "with 4 mg per axis: 0.2292 deg" in capsys.readouterr().out
    assert main(["camber", "bound", "--lsb-mg", "0.0001"]) == 0
    assert "with 0.0001 mg per axis: 5.73e-06 deg" in capsys.readouterr().out


def test_unknown_verb_and_flags(capsys):
    with pytest.raises(SystemExit) as e:
        main(["fly"])
    assert e.value.code == 2
    with pytest.raises(SystemExit) as e:
        main(["daemon", "--mode", "warp"])
    assert e.value.code == 2


def test_study_lists_every_topic_and_each_one_parses_its_own_flags(capsys):
    """`vehest-can study` lists the systems' studies and the house's; each topic's own parser runs
    (`--help`: exit 0 with the verb's program name); an unknown topic names the valid ones."""
    from vehest_can.cli import study

    assert main(["study"]) == 0
    listed = [line.split()[0] for line in capsys.readouterr().out.splitlines()]
    assert listed == sorted(study.topics()) and {"roll.control", "tireforce.bound", "firmware.cost"} <= set(listed)
    for topic in listed:
        with pytest.raises(SystemExit) as e:
            main(["study", topic, "--help"])
        assert e.value.code == 0 and f"usage: vehest-can study {topic}" in capsys.readouterr().out
    assert main(["study", "roll.nothing"]) == 1
    assert "roll.control" in capsys.readouterr().err
