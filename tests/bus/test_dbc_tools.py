"""Every bundled DBC as the DBC tools read it: canmatrix and cantools, not our own parser.

Each cyclic frame must show as cyclic with the cycle time the firmware runs (``CycleTimeUs``, the
source of the generated schedule), every signal must name who receives it, and the simulator's
lockstep frames must live in the simulator's DBC only (docs/busload.md)."""
from __future__ import annotations

from pathlib import Path

import canmatrix.formats
import cantools
import pytest

from vehest_can.bus.frames import BUSES, SIM
from vehest_can.native import lib
from vehest_can.paths import dbc_path
from vehest_can.xcp import ecu_desc

DBCS = {name: dbc_path(name) for name in (*BUSES, SIM)} | {"xcp": ecu_desc.SHIPPED_DBC}


def _canmatrix(path: Path):
    return canmatrix.formats.loadp_flat(str(path))


def cycle_problems(path: Path) -> list[str]:
    """Frames whose cycle, as cantools and canmatrix report it, is not the project's schedule."""
    ct = cantools.database.load_file(str(path), strict=False)
    cm = {f.arbitration_id.id: f for f in _canmatrix(path).frames}
    out = []
    for m in ct.messages:
        attrs = m.dbc.attributes if m.dbc else {}
        us = int(attrs["CycleTimeUs"].value) if "CycleTimeUs" in attrs else 0
        f = cm[m.frame_id]
        cm_ms = f.attribute("GenMsgCycleTime")
        if not us:  # an event frame: no tool may call it cyclic
            if m.send_type == "Cyclic" or m.cycle_time or f.cycle_time:
                out.append(f"{m.name}: cyclic in a tool, no CycleTimeUs")
            continue
        if m.send_type != "Cyclic" or m.cycle_time is None or round(m.cycle_time * 1000) != us:
            out.append(f"{m.name}: cantools {m.send_type} {m.cycle_time} ms, schedule {us} us")
        if f.attribute("GenMsgSendType") != "Cyclic" or cm_ms is None or round(float(cm_ms) * 1000) != us:
            out.append(f"{m.name}: canmatrix {f.attribute('GenMsgSendType')} {cm_ms} ms, schedule {us} us")
        # canmatrix keeps cycle_time in whole ms (int(float(GenMsgCycleTime)) in its DBC reader): exact
        # from 1 ms up, 0 for the 500 us frames, whose exact time is its GenMsgCycleTime attribute
        if f.cycle_time != us // 1000 or f.effective_cycle_time != us // 1000:
            out.append(f"{m.name}: canmatrix cycle_time {f.cycle_time}, effective {f.effective_cycle_time}")
    return out


def receiver_problems(path: Path) -> list[str]:
    """Signals with no receiver (or the placeholder Vector__XXX), or a receiver that is no node."""
    ct = cantools.database.load_file(str(path), strict=False)
    nodes = {n.name for n in ct.nodes}
    cm = {f.arbitration_id.id: f for f in _canmatrix(path).frames}
    out = []
    for m in ct.messages:
        for s in m.signals:
            if not s.receivers or not set(s.receivers) <= nodes - {"Vector__XXX"}:
                out.append(f"{m.name}.{s.name}: receivers {s.receivers}")
        if m.signals and not set(cm[m.frame_id].receivers) <= nodes - {"Vector__XXX"}:
            out.append(f"{m.name}: canmatrix receivers {cm[m.frame_id].receivers}")
    return out


@pytest.mark.parametrize("name", DBCS)
def test_every_cyclic_frame_shows_its_schedule_in_cantools_and_canmatrix(name):
    assert cycle_problems(DBCS[name]) == []


def test_the_2khz_frames_in_both_tools():
    """The three 500 us frames: 0.5 ms in cantools and in canmatrix's attribute, the ECU's tick."""
    for bus, names in (("pt", ("DLS_Sensors", "VEHEST_DrivelineEst")), ("ch", ("CHS_Sensors",))):
        ct = cantools.database.load_file(str(dbc_path(bus)))
        cm = {f.name: f for f in _canmatrix(dbc_path(bus)).frames}
        for n in names:
            assert ct.get_message_by_name(n).cycle_time * 1000 == lib.VH_TICK_US
            assert float(cm[n].attribute("GenMsgCycleTime")) * 1000 == lib.VH_TICK_US


@pytest.mark.parametrize("name", [*BUSES, SIM])
def test_every_signal_names_its_receivers(name):
    assert receiver_problems(DBCS[name]) == []
    db = cantools.database.load_file(str(DBCS[name]))
    assert any("VEHEST" in m.senders for m in db.messages)  # the ECU's outputs are among them


def test_simulator_frames_are_only_in_the_simulator_dbc():
    sim = cantools.database.load_file(str(dbc_path(SIM)))
    assert {m.name for m in sim.messages} == {"SIM_Sync", "VEHEST_SyncAck"}
    ids = {m.frame_id for m in sim.messages}
    for bus in BUSES:
        db = cantools.database.load_file(str(dbc_path(bus)))
        assert not {m.frame_id for m in db.messages} & ids
        assert not [m.name for m in db.messages if "SIM" in m.senders or m.name.startswith("SIM_")]


@pytest.mark.parametrize("broken, problem", [
    ('BA_ "GenMsgCycleTime" BO_ 256 0.5;\n', "DLS_Sensors: cantools Cyclic None ms"),  # CycleTimeUs alone
    ('BA_ "GenMsgSendType" BO_ 384 0;\n', "VEHEST_DrivelineEst: cantools Event"),        # cyclic, not said
])
def test_the_cycle_check_fails_on_a_broken_dbc(tmp_path, broken, problem):
    text = dbc_path("pt").read_text()
    assert broken in text
    path = tmp_path / "broken.dbc"
    path.write_text(text.replace(broken, ""))
    assert any(p.startswith(problem) for p in cycle_problems(path)), cycle_problems(path)


def test_the_receiver_check_fails_on_a_broken_dbc(tmp_path):
    text = dbc_path("ch").read_text()
    line = ' SG_ RollFade : 88|8@1+ (0.005,0) [0|1] "" TESTER'
    assert line in text
    path = tmp_path / "broken.dbc"
    path.write_text(text.replace(line, line.replace("TESTER", "Vector__XXX")))
    assert receiver_problems(path) == ["VEHEST_RollEst.RollFade: receivers []"]
