"""`vehest-can daemon` (its own process, real time) with XCP on a bus of its own: python-can's
prefixed bus flags (--xcp-interface, --xcp-channel, --xcp-bus-kwargs), udp_multicast on loopback,
the ECU's bus and the XCP bus on private ports. The car and a listener on the ECU's bus, pyxcp on
the XCP bus: pyxcp's DAQ of the driveline filters' internals equals the VEHEST_DrivelineEst frames
the same daemon transmits, matched by ECU tick and E2E alive counter.

VEHEST_XCP_RT_SECONDS (default 2) sets the DAQ length."""
from __future__ import annotations

import json
import os
import threading
import time

import can
import numpy as np
import pytest
from daemonproc import start_daemon, stop_daemon

from vehest_can.bus import bus as busmod
from vehest_can.bus.frames import database
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.sim.session import SimMaster
from vehest_can.systems.driveline.scenario import load_driveline_scenario
from vehest_can.xcp import ecu as xcp_ecu
from vehest_can.xcp.description import C_TYPES
from vehest_can.xcp.keys import write_key

pytestmark = pytest.mark.multicast
pytest.importorskip("pyxcp")
from pyxcp.daq_stim import DaqList  # noqa: E402
from xcp_daq_policy import Collect, one_offset  # noqa: E402

EST = database("pt").get_message_by_name("VEHEST_DrivelineEst")
#: DAQ measurement -> its signal in VEHEST_DrivelineEst
SIGNALS = {"app.drv.dkf[0].x[2]": "DkfT_ShaftTorque", "app.drv.dkf[0].x[3]": "DkfT_RoadLoadErr",
           "app.drv.dkf[1].x[2]": "DkfS_ShaftTorque", "app.drv.dkf[1].x[3]": "DkfS_RoadLoadErr",
           "app.drv.dkf[0].health": "DkfT_Health", "app.drv.dkf[1].health": "DkfS_Health"}
N_COUNTER = 15  # E2E P01 alive counter 0..14


def _unwrap(counters: list[int]) -> list[int]:
    """Frame indices from alive counters (a gap of g counts g - 1 lost frames)."""
    idx = [0]
    for a, b in zip(counters, counters[1:]):
        idx.append(idx[-1] + (b - a - 1) % N_COUNTER + 1)
    return idx


def test_daq_over_the_daemon_on_its_own_xcp_bus_equals_its_estimate_frames(pyxcp_master, tmp_path):
    seconds = float(os.environ.get("VEHEST_XCP_RT_SECONDS", "2"))
    main, xcp = busmod.private_multicast(), busmod.private_multicast()
    stats = tmp_path / "stats.json"
    key = write_key(tmp_path / "xcp.key")  # the user's key file, mode 600
    proc = start_daemon(main, "--mode", "realtime", "--xcp", "on", "--xcp-key", str(tmp_path / "xcp.key"),
                        "--xcp-interface", "udp_multicast", "--xcp-channel", xcp["channel"],
                        "--xcp-bus-kwargs", f"port={xcp['port']}", "--stats", str(stats), tmp_path=tmp_path)
    car_bus, listen_bus, master_bus = busmod.open_bus(main), busmod.open_bus(main), busmod.open_bus(xcp)
    desc = xcp_ecu.description()
    est: list[can.Message] = []
    xcp_on_main: list[can.Message] = []

    def hear(msg: can.Message) -> None:
        if msg.arbitration_id == EST.frame_id:
            est.append(msg)
        elif msg.arbitration_id == desc.dto_id:  # (the one CRO there is the test's own)
            xcp_on_main.append(msg)
    notifier = can.Notifier(listen_bus, [hear], timeout=0.01)
    car = threading.Thread(target=SimMaster(car_bus, powertrain_car(load_driveline_scenario("launch_2nd"), seconds + 4.0))
                           .run_realtime, daemon=True)
    car.start()
    try:
        # a CONNECT on the vehicle bus: the slave listens on its own bus only (not answered, counted)
        car_bus.send(can.Message(arbitration_id=desc.cro_id, is_extended_id=False, is_fd=True, data=bytes([0xFF, 0])))
        m = pyxcp_master(None, desc, bus=master_bus, timeout=2.0, key=key)
        m.__enter__()
        m.connect()
        m.getCommModeInfo()
        assert m.identifier(1) == "VEHEST_ECU"  # the slave answers on the XCP bus
        m.cond_unlock("daq")
        names = ["tick", "app.drv.tx_counter[0]", *SIGNALS]
        rows = [(n, desc.item(n).address, 0, C_TYPES[desc.item(n).ctype][3]) for n in names]
        policy = Collect([DaqList(name="est", event_num=1, stim=False, enable_timestamps=True, measurements=rows,
                                  priority=0, prescaler=1)])
        m.transport.policy = policy
        policy.xcp_master = m
        time.sleep(1.0)  # the car is driving
        policy.setup()
        policy.start()
        time.sleep(seconds)
        policy.stop()
        time.sleep(0.3)
        m.disconnect()
        m.__exit__(None, None, None)
    finally:
        car.join(60)  # the car's drive ends by itself; its bus stays open until then
        notifier.stop()
        rc, err = stop_daemon(proc)
        for b in (car_bus, listen_bus, master_bus):
            b.shutdown()
    assert rc == 0, err
    assert f"XCP bus udp_multicast {xcp['channel']} port {xcp['port']}" in err
    doc = json.loads(stats.read_text())
    buses = doc["buses"]
    assert doc["xcp"]["cro_foreign"] == 1 and doc["xcp"]["own_bus"] == 1 and doc["xcp"]["key_fail"] == 0
    assert "xcp: " in err and "cro_foreign=1" in err  # the exit line
    assert set(buses) == {"vcan0", "xcp"} and buses["xcp"]["tx"] > 0, buses  # the ECU's bus by its log channel
    assert xcp_on_main == []  # every XCP frame on the XCP bus, none on the ECU's

    col = {h[0]: k for k, h in enumerate(policy.daq_lists[0].headers)}  # pyxcp's packing order
    daq = [{n: p[col[n]] for n in names} for _, _, p in policy.samples]
    ticks = [s["tick"] for s in daq]
    assert len(daq) > 100 and all(b - a == 2 for a, b in zip(ticks, ticks[1:]))  # 1 ms list, none lost
    frames = [EST.decode(bytes(msg.data), decode_choices=False) for msg in est]
    idx = _unwrap([f["DLE_Counter"] for f in frames])
    by_idx = dict(zip(idx, frames))
    # The sample of ECU tick t read drv.tx_counter[0] after that tick's frame went out (the events run
    # after the systems' TX): the frame's counter is one less. Frame index = t - offset, one offset.
    mid = daq[len(daq) // 2]
    candidates = {mid["tick"] - i for i, f in by_idx.items()
                  if f["DLE_Counter"] == (mid["app.drv.tx_counter[0]"] - 1) % N_COUNTER}

    def same(s: dict, f: dict) -> bool:
        return f["DLE_Counter"] == (s["app.drv.tx_counter[0]"] - 1) % N_COUNTER and all(
            abs(s[name] - f[sig]) <= (0 if "health" in name else 0.125 + 1e-9) for name, sig in SIGNALS.items())
    _, n = one_offset(daq, by_idx, candidates, same)
    torque = np.array([s["app.drv.dkf[0].x[2]"] for s in daq])
    print(f"DAQ over the daemon's XCP bus: {len(daq)} samples (ECU ticks {ticks[0]}..{ticks[-1]}), {n} matched to "
          f"VEHEST_DrivelineEst by tick and alive counter ({len(est)} frames heard, {idx[-1] + 1 - len(est)} "
          f"lost by their counters), all equal within 0.125 Nm, health exact; shaft torque "
          f"{torque.min():.0f}..{torque.max():.0f} Nm")
    assert n >= 0.9 * len(daq)
    assert np.ptp(torque) > 100.0  # the launch moves the estimate: not a comparison of constants


def test_a_daemon_with_default_flags_answers_no_xcp_frame(tmp_path):
    """XCP is off by default: a CONNECT on the daemon's bus gets no answer (and no XCP line at exit)."""
    main = busmod.private_multicast()
    stats = tmp_path / "stats.json"
    proc = start_daemon(main, "--mode", "realtime", "--stats", str(stats), tmp_path=tmp_path)
    bus = busmod.open_bus(main)
    desc = xcp_ecu.description()
    heard: list[can.Message] = []
    try:
        for _ in range(3):
            bus.send(can.Message(arbitration_id=desc.cro_id, is_extended_id=False, is_fd=True, data=bytes([0xFF, 0])))
            end = time.monotonic() + 1.0
            while (left := end - time.monotonic()) > 0:
                msg = bus.recv(left)
                if msg is not None and msg.arbitration_id == desc.dto_id:
                    heard.append(msg)
    finally:
        rc, err = stop_daemon(proc)
        bus.shutdown()
    assert rc == 0, err
    assert heard == [] and "xcp:" not in err and "xcp" not in json.loads(stats.read_text())
    print("default daemon: 3 CONNECTs on its bus, 0 XCP frames in 3 s")
