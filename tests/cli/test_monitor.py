"""`vehest-can monitor`: the ECU's estimates, validity, health and counters, decoded through the
DBCs; from an in-process session, from a running daemon over the bus, and on a terminal (tmux)."""
import re
import shutil
import subprocess
import sys
import time

import can
import pytest
from daemonproc import start_daemon, stop_daemon

from vehest_can.bus.bus import cli_args, private_multicast
from vehest_can.service.monitor import Monitor, compile_filter
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.sim.session import run_inprocess
from vehest_can.systems.driveline.scenario import load_driveline_scenario
from vehest_can.systems.ecu import Ecu


def test_monitor_shows_the_latest_decoded_values():
    s = run_inprocess(powertrain_car(load_driveline_scenario("launch_2nd"), duration_s=1.0), Ecu())
    mon = Monitor()
    for k, m in zip(s.frame_tick, s.messages()):
        mon.feed(m, now=k * 0.0005)
    screen = mon.render(100, now=1.0)
    text = "\n".join(screen)
    assert max(map(len, screen)) <= 100
    assert "VEHEST_DrivelineEst: 2000 frames, 2000/s" in text and "DkfT_Health=OK" in text
    assert "DkfT_Valid=VALID" in text and "CntCrcError=0" in text and "Nm" in text
    assert "VEHEST_TireForceEst: not heard" in text  # no chassis in this session
    # every frame decoded, the sensor node's too (not counted as "other")
    assert "DLS_Sensors: 2000 frames, 2000/s" in text and "EngineSpeed=" in text
    assert "0 IDs in no DBC, 0 undecodable" in screen[0]
    assert "_CRC=" not in text and "_Counter=" not in text  # change every frame: left out


def test_monitor_filter_and_raw_view():
    s = run_inprocess(powertrain_car(load_driveline_scenario("launch_2nd"), duration_s=0.2), Ecu())
    mon = Monitor()
    for k, m in zip(s.frame_tick, s.messages()):
        mon.feed(m, now=k * 0.0005)
    mon.feed(can.Message(arbitration_id=0x7E5, is_extended_id=False, data=b"\x01\x02"), now=0.2)
    by_signal = "\n".join(mon.body(100, now=0.2, pattern=compile_filter("cnttimeout")))
    assert by_signal.splitlines()[1].split() == ["CntTimeout=0"] and "DLS_Sensors" not in by_signal
    by_id = "\n".join(mon.body(100, now=0.2, pattern=compile_filter("0x100")))
    assert re.match(r"pt +100 DLS_Sensors:", by_id) and "EngineSpeed=" in by_id and "VEHEST" not in by_id
    assert mon.body(100, pattern=compile_filter("CntTime(")) == []  # not a regex: taken literally, no match
    raw = mon.body(100, now=0.2, raw=True)
    assert any(re.match(r"pt +100", line) and "FD BRS [20]" in line for line in raw)
    assert any("7E5" in line and "(in no DBC)" in line and "CAN [2] 01 02" in line for line in raw)
    assert not any("not heard" in line for line in raw) and max(map(len, raw)) <= 100
    frozen = mon.snapshot()
    mon.feed(s.messages().__next__(), now=0.3)
    assert frozen.frames == mon.frames - 1


@pytest.mark.multicast
def test_monitor_of_a_running_daemon(tmp_path):
    config = private_multicast()
    daemon = start_daemon(config, "--mode", "realtime", tmp_path=tmp_path)
    try:
        out = subprocess.run([sys.executable, "-m", "vehest_can.cli", "monitor", "--once", "--duration", "2",
                              *cli_args(config)], capture_output=True, text=True, timeout=60)
    finally:
        stop_daemon(daemon)
    assert out.returncode == 0, out.stderr
    assert "VEHEST_Status:" in out.stdout and "DkfT_HealthSts=INIT" in out.stdout  # nothing to estimate from
    assert "CntTimeout=" in out.stdout and "not heard" in out.stdout


@pytest.mark.multicast
@pytest.mark.skipif(shutil.which("tmux") is None, reason="tmux not installed")
def test_monitor_in_a_terminal(tmp_path):
    """Redrawn in place on a 100x40 terminal (tmux), against a daemon and the simulated car."""
    config = private_multicast()
    daemon = start_daemon(config, "--mode", "realtime", tmp_path=tmp_path)
    name = f"vehest-monitor-{tmp_path.name}"
    cmd = " ".join([sys.executable, "-m", "vehest_can.cli", "monitor", "--duration", "20", *cli_args(config)])
    car = None
    try:
        subprocess.run(["tmux", "new-session", "-d", "-s", name, "-x", "100", "-y", "45", cmd], check=True)
        car = subprocess.Popen([sys.executable, "-m", "vehest_can.cli", "sim", "launch_2nd", "--duration", "6",
                                *cli_args(config)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        screen = ""
        for _ in range(60):
            time.sleep(0.5)
            screen = subprocess.run(["tmux", "capture-pane", "-p", "-t", name], capture_output=True, text=True).stdout
            if "DkfT_Health=OK" in screen:
                break
        (tmp_path / "screen.txt").write_text(screen)
        assert screen.startswith("vehest-can monitor:") and "VEHEST_DrivelineEst" in screen, screen
        assert "DkfT_Health=OK" in screen, screen
        assert max(len(line) for line in screen.splitlines()) <= 100
    finally:
        subprocess.run(["tmux", "kill-session", "-t", name], capture_output=True)
        if car is not None:
            car.kill()
            car.wait()
        stop_daemon(daemon)
