"""The XCP slave inside the ECU firmware: its CRO through the ECU's dispatch, its frames in the
ECU's TX, the ECU's own memory and tuning, the build's A2L and limit table never stale.

These drive the firmware with raw CRO frames (command codes of ASAM MCD-1 XCP Part 2) so a
failure points at the firmware; pyxcp, the independent master, runs against the daemon in
tests/service/test_daemon_xcp.py."""
from __future__ import annotations

import re
import shutil
import struct
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import can
import numpy as np
import pytest

from vehest_can.native import ffi
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.sim.session import run_inprocess
from vehest_can.systems.driveline.scenario import load_driveline_scenario
from vehest_can.systems.driveline.system import EcuPart
from vehest_can.systems.ecu import Ecu, EcuConfig
from vehest_can.xcp import ecu as xcp_ecu
from vehest_can.xcp import ecu_desc
from vehest_can.xcp.description import C_TYPES
from vehest_can.xcp.keys import key_for

ROOT = Path(__file__).resolve().parents[2]
ERR = 0xFE
ERR_OUT_OF_RANGE, ERR_WRITE_PROTECTED, ERR_ACCESS_DENIED, ERR_ACCESS_LOCKED = 0x22, 0x23, 0x24, 0x25
ERR_RESOURCE_TEMPORARY_NOT_ACCESSIBLE = 0x33
#: RFC 4493's published AES-128 test key: the tests' seed & key key (a test vector, not a secret)
KEY = bytes.fromhex("2b7e151628aed2a6abf7158809cf4f3c")


class Cro:
    """CRO frames into an ECU, one tick per command (the RES comes out of that tick's TX)."""

    def __init__(self, ecu: Ecu, **kw):
        self.ecu = ecu
        self.desc = xcp_ecu.enable(ecu, KEY, **kw)
        self.other: list[can.Message] = []

    def __call__(self, *data: int) -> bytes:
        self.ecu.rx(can.Message(arbitration_id=self.desc.cro_id, is_extended_id=False, is_fd=self.desc.fd,
                                data=bytes(data)))
        out = self.ecu.step()
        res = [m for m in out if m.arbitration_id == self.desc.dto_id]
        self.other += [m for m in out if m.arbitration_id != self.desc.dto_id]
        assert len(res) == 1, res
        return bytes(res[0].data)

    def connect_unlocked(self) -> None:
        assert self(0xFF, 0)[0] == 0xFF                    # CONNECT
        for resource in (0x01, 0x04):                      # CAL/PAG, DAQ
            seed = self(0xF8, 0, resource)                 # GET_SEED
            assert self(0xF7, 6, *key_for(seed[2:8], resource, KEY))[0] == 0xFF  # UNLOCK

    def set_mta(self, address: int) -> bytes:
        return self(0xF6, 0, 0, 0, *struct.pack("<I", address))

    def download(self, address: int, raw: bytes) -> bytes:
        """DOWNLOAD in chunks of MAX_CTO - 2; the last answer."""
        assert self.set_mta(address)[0] == 0xFF
        step = self.desc.max_cto - 2
        for i in range(0, len(raw), step):
            chunk = raw[i:i + step]
            r = self(0xF0, len(chunk), *chunk)
            if r[0] != 0xFF:
                return r
        return r

    def upload(self, address: int, n: int) -> bytes:
        r = self(0xF4, n, 0, 0, *struct.pack("<I", address))  # SHORT_UPLOAD
        assert r[0] == 0xFF, r.hex()
        return r[1:1 + n]


def torque_r(desc) -> int:
    """Address of dkf[0].r[2], the driveline filter's torque-sensor variance."""
    return desc.item("cal.app.drv.dkf[0].r").address + 2 * 8


# ---- the description, the A2L and the limit table: from the C structs, never stale --------

def test_the_limit_table_a2l_and_dbc_are_the_build_output_of_these_structs():
    """Regenerated from the compiled module's structs: equal to what the build wrote and the
    firmware was compiled with (c_core/ecu/vh_ecu_xcp_table.inc), so none of them is stale."""
    outputs = ecu_desc.outputs(xcp_ecu.description())
    assert ecu_desc.TABLE in outputs and ecu_desc.SHIPPED_A2L in outputs
    for target, text in outputs.items():
        assert target.read_text() == text, f"{target} is stale: regenerate it (python c_core/ecu_gen.py) and commit it"


def test_addresses_are_the_c_offsets_and_names_the_c_members():
    desc = xcp_ecu.description()
    ecu = Ecu()
    base = int(ffi.cast("uintptr_t", ecu.c))
    assert desc.item("app.drv.dkf[0].x[2]").address - desc.measurement_address == \
        int(ffi.cast("uintptr_t", ffi.addressof(ecu.c.app.drv.dkf[0], "x"))) \
        + 2 * ffi.sizeof(ffi.typeof(ecu.c.app.drv.dkf[0].x).item) - base
    assert desc.item("cal.app.tf.skf.r").address - desc.calibration_address == \
        ffi.offsetof("vh_ecu_cal_t", "app", "tf", "skf", "r")
    names = {it.name for it in desc.measurements}
    for system in ("app.drv.dkf[0].x[3]", "app.drv.dkf[1].p[15]", "app.drv.dkf[0].innov[2]",  # driveline
                   "app.drv.dkf[0].health",
                   "app.tf.skf.x[6]", "app.tf.skf.p[48]", "app.tf.skf.innov[3]", "app.tf.skf.health",  # tyre force
                   "app.camber.last[3].theta_rad",                                                  # camber
                   "cnt.crc_error", "app.tf.cnt.saturation", "xcp.slave.n.err_range"):              # counters
        assert system in names
    assert {it.name for it in desc.characteristics} >= {
        "cal.app.drv.dkf[0].q", "cal.app.drv.dkf[0].r", "cal.app.drv.dkf[1].r", "cal.app.tf.skf.q", "cal.app.tf.skf.r",
        "cal.app.drv.we_min", "cal.app.camber.mag_tol_g", "cal.rx_burst_frames"}
    assert len(desc.measurements) >= 20


def test_a_member_that_is_not_in_the_structs_is_refused(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(ecu_desc.ECU_TOML.read_text().replace('c = "app.drv.dkf[0].x"', 'c = "app.drv.dkf[0].xx"'))
    with pytest.raises(ecu_desc.DescriptionError, match="no member"):
        ecu_desc.describe(ffi, bad)


def test_pya2l_and_a2ltool_open_it_without_errors():
    parser = pytest.importorskip("pya2l.parser")
    desc = xcp_ecu.description()
    text = ecu_desc.SHIPPED_A2L.read_bytes()
    with parser.A2lParser() as p:
        tree = p.tree_from_a2l(text)
        # pya2l 0.4's quirk inside IF_DATA (see test_xcp_a2l.py); nothing else
        assert all("may be used at most once" in w for w in p.warnings), p.warnings
        m = tree.PROJECT.MODULE[0]
        assert {x.Name.Value: x.ECU_ADDRESS.Address.Value for x in m.MEASUREMENT} == \
            {x.name: x.address for x in desc.measurements}
        assert {x.Name.Value for x in m.CHARACTERISTIC} == {x.name for x in desc.characteristics}
        p.tree_from_a2l(re.sub(rb"/begin IF_DATA.*?/end IF_DATA", b"", text, flags=re.S), enforce_version_check=True)
        assert p.warnings == []
    a2ltool = shutil.which("a2ltool") or str(Path(sys.executable).with_name("a2ltool"))
    if Path(a2ltool).exists():
        r = subprocess.run([a2ltool, "--check", "--strict", str(ecu_desc.SHIPPED_A2L)], capture_output=True, text=True)
        assert r.returncode == 0 and "No problems found" in r.stdout, r.stdout + r.stderr


def test_the_reference_page_is_the_configuration_and_within_the_limits():
    ecu = Ecu()
    xcp_ecu.enable(ecu, KEY)
    for it in xcp_ecu.description().characteristics:
        lo, hi = it.phys_limits()
        vals = np.atleast_1d(xcp_ecu.read(ecu, it.name, "ref"))
        assert np.all((vals >= lo) & (vals <= hi)), it.name
        assert list(np.atleast_1d(xcp_ecu.read(ecu, it.name, "page"))) == list(vals)
    assert xcp_ecu.read(ecu, "cal.app.drv.dkf[0].r", "ref") == list(ecu.c.app.drv.cfg.dkf[0].r)


# ---- measurement: the ECU's own memory ------------------------------------------------------

def test_upload_reads_the_running_filters():
    ecu = Ecu()
    cro = Cro(ecu, max_cto=64)  # CAN FD: a double in one SHORT_UPLOAD (at most MAX_CTO - 1 bytes)
    cro(0xFF, 0)
    drive = powertrain_car(load_driveline_scenario("launch_2nd"), 0.3)
    run_inprocess(drive, ecu)  # the filters have run: the states are not zero
    desc = cro.desc
    # the innovation first: the ticks of the commands have no sensor frame (prediction only)
    for name, value in (("app.drv.dkf[0].innov[0]", lambda: ecu.c.app.drv.dkf[0].innov[0]),
                        ("app.drv.dkf[0].x[2]", lambda: ecu.c.app.drv.dkf[0].x[2]),
                        ("app.drv.dkf[0].p[5]", lambda: ecu.c.app.drv.dkf[0].p[5])):
        value = value()  # now: each command is a tick (the filters predict on)
        assert value != 0.0
        assert struct.unpack("<f", cro.upload(desc.item(name).address, 4))[0] == value  # the ECU's filters: float32
    assert struct.unpack("<I", cro.upload(desc.item("tick").address, 4))[0] == ecu.tick - 1


# ---- calibration: range-checked, at the tick boundary, bit-exact ----------------------------

def test_a_write_reaches_the_filter_at_the_next_tick_boundary_and_survives_a_reset():
    ecu = Ecu()
    cro = Cro(ecu)
    cro.connect_unlocked()
    raw = struct.pack("<d", 1234.5)
    assert cro.download(torque_r(cro.desc) - 16 + 16, raw[:6])[0] == 0xFF
    assert ecu.c.app.drv.dkf[0].cfg.r[2] != 1234.5  # half a double written: nothing reaches the filter
    r = cro(0xF0, 2, *raw[6:])               # the last byte: due at the next tick boundary ...
    assert r[0] == 0xFF and ecu.c.app.drv.dkf[0].cfg.r[2] == 1234.5  # ... which this command's tick was
    assert xcp_ecu.read(ecu, "cal.app.drv.dkf[0].r", "ref")[2] != 1234.5  # the reference page never changes
    ecu.reset()
    assert ecu.c.app.drv.dkf[0].cfg.r[2] == 1234.5 and ecu.c.app.drv.cfg.dkf[0].r[2] == 1234.5


def test_out_of_range_locked_and_reference_page_writes_are_refused_and_counted():
    ecu = Ecu()
    cro = Cro(ecu)
    assert cro(0xFF, 0)[0] == 0xFF
    a = torque_r(cro.desc)
    before = ecu.c.app.drv.dkf[0].cfg.r[2]
    assert cro.download(a, struct.pack("<d", 5.0)[:6])[:2] == bytes([ERR, ERR_ACCESS_LOCKED])
    cro.connect_unlocked()
    for bad in (-1.0, 2e9, float("nan")):  # below 1e-6, above 1e9, NaN: the A2L's limits
        assert cro.download(a, struct.pack("<d", bad))[:2] == bytes([ERR, ERR_OUT_OF_RANGE])
    assert cro(0xEB, 0x83, 0, 1)[0] == 0xFF   # SET_CAL_PAGE: the master on the reference page
    assert cro.download(a, struct.pack("<d", 5.0))[:2] == bytes([ERR, ERR_WRITE_PROTECTED])
    assert cro.download(cro.desc.calibration_address + ffi.sizeof("vh_ecu_cal_t") + 8, b"\0")[:2] == \
        bytes([ERR, ERR_ACCESS_DENIED])
    for _ in range(3):
        ecu.step()
    assert ecu.c.app.drv.dkf[0].cfg.r[2] == before
    n = xcp_ecu.counters(ecu)
    assert n["err_locked"] == 1 and n["err_range"] == 3 and n["err_access"] == 2 and n["cal_commits"] == 0


def test_a_refused_value_written_in_two_downloads_leaves_no_byte_behind():
    """A double over classic-size CTOs takes two DOWNLOADs; the second completes it out of range:
    the first one's six bytes go too (found against the daemon: the mix of the old value's last
    bytes and the refused value's first ones was in range and would have been committed)."""
    ecu = Ecu()
    cro = Cro(ecu)
    cro.connect_unlocked()
    a = torque_r(cro.desc)
    assert cro.download(a, struct.pack("<d", 1.0e6))[0] == 0xFF
    assert cro.download(a, struct.pack("<d", -5.0))[:2] == bytes([ERR, ERR_OUT_OF_RANGE])
    for _ in range(250):  # past open_ticks: nothing is left open to commit
        ecu.step()
    assert xcp_ecu.read(ecu, "cal.app.drv.dkf[0].r", "work")[2] == 1.0e6 == ecu.c.app.drv.dkf[0].cfg.r[2]
    assert xcp_ecu.counters(ecu)["cal_dropped"] == 0


def test_the_ecu_runs_on_the_reference_page_when_switched_to_it():
    ecu = Ecu()
    cro = Cro(ecu)
    cro.connect_unlocked()
    cro.download(torque_r(cro.desc), struct.pack("<d", 777.0))
    ecu.step()
    assert ecu.c.app.drv.dkf[0].cfg.r[2] == 777.0
    assert cro(0xEB, 0x01, 0, 1)[0] == 0xFF   # SET_CAL_PAGE for the ECU: page 1
    ecu.step()
    assert ecu.c.app.drv.dkf[0].cfg.r[2] == xcp_ecu.read(ecu, "cal.app.drv.dkf[0].r", "ref")[2]


def _estimates(session) -> np.ndarray:
    from vehest_can.bus.frames import frame_id
    est = frame_id("VEHEST_DrivelineEst")
    f = session.frames
    return f[f["id"] == est]


def test_a_calibration_write_is_bit_exact_with_the_same_value_set_at_start():
    """Lockstep: the torque-sensor variance written through XCP before the drive gives the same
    estimate frames, bit for bit, as an ECU configured with that value; and not the default's."""
    drive = powertrain_car(load_driveline_scenario("launch_2nd"), 1.0)
    value = 4.0 * Ecu().c.app.drv.cfg.dkf[0].r[2]
    part = EcuPart.default()
    started = Ecu(EcuConfig(systems={"driveline": replace(part, dkf_t=replace(part.dkf_t, r=(*part.dkf_t.r[:2], value)))}))
    assert started.c.app.drv.cfg.dkf[0].r[2] == value
    calibrated = Ecu()
    cro = Cro(calibrated)
    cro.connect_unlocked()
    assert cro.download(torque_r(cro.desc), struct.pack("<d", value))[0] == 0xFF
    calibrated.reset()  # the session's reset (SIM_Sync RESET): the calibration stays
    a, b, default = (_estimates(run_inprocess(drive, e)) for e in (started, calibrated, Ecu()))
    assert len(a) == len(b) > 1000
    # field by field: a frame record's two padding bytes are not part of it (tobytes() would read them)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, default)


def test_xcp_idle_changes_no_frame_of_the_systems():
    drive = powertrain_car(load_driveline_scenario("launch_2nd"), 0.5)
    with_xcp = Ecu()
    xcp_ecu.enable(with_xcp, KEY)
    a, b = run_inprocess(drive, Ecu()).frames, run_inprocess(drive, with_xcp).frames
    assert np.array_equal(a, b)


# ---- bad input and the TX budget -------------------------------------------------------------

def test_bad_cro_frames_are_errors_never_a_crash():
    ecu = Ecu()
    cro = Cro(ecu)
    cro(0xFF, 0)
    assert cro(0x42)[:2] == bytes([ERR, 0x20])          # ERR_CMD_UNKNOWN
    assert cro(0xF6)[:2] == bytes([ERR, 0x21])          # SET_MTA without its address: ERR_CMD_SYNTAX
    assert cro(0xF4, 4, 0, 0, 0, 0, 0, 0x30)[:2] == bytes([ERR, ERR_ACCESS_DENIED])  # outside described memory
    # a DAQ list over the capacities (ALLOC_DAQ 200 > VH_XCP_MAX_DAQ) while locked / unlocked
    assert cro(0xD5, 0, 200, 0)[:2] == bytes([ERR, ERR_ACCESS_LOCKED])
    cro.connect_unlocked()
    assert cro(0xD6)[0] == 0xFF
    assert cro(0xD5, 0, 200, 0)[:2] == bytes([ERR, 0x30])  # ERR_MEMORY_OVERFLOW
    n = xcp_ecu.counters(ecu)
    assert n["err_unknown"] == 1 and n["err_syntax"] == 1 and n["err_access"] == 1 and n["err_daq"] == 1
    # our own DTO identifier heard back (udp_multicast loops frames back) is known, not input
    cro_before = n["cro"]
    ecu.rx(can.Message(arbitration_id=cro.desc.dto_id, is_extended_id=False, is_fd=True, data=b"\xff"))
    assert ecu.counters()["unknown_id"] == 0 and xcp_ecu.counters(ecu)["cro"] == cro_before


def start_daq(cro: Cro, odts: list, event: int, timestamp: bool = True) -> None:
    """One dynamic DAQ list of the given ODTs (lists of Items) on an event channel, started."""
    assert cro(0xD6)[0] == 0xFF                                   # FREE_DAQ
    assert cro(0xD5, 0, 1, 0)[0] == 0xFF                          # ALLOC_DAQ 1
    assert cro(0xD4, 0, 0, 0, len(odts))[0] == 0xFF               # ALLOC_ODT
    for i, odt in enumerate(odts):
        assert cro(0xD3, 0, 0, 0, i, len(odt))[0] == 0xFF         # ALLOC_ODT_ENTRY
    for i, odt in enumerate(odts):
        assert cro(0xE2, 0, 0, 0, i, 0)[0] == 0xFF                # SET_DAQ_PTR
        for it in odt:
            assert cro(0xE1, 0xFF, it.size, 0, *struct.pack("<I", it.address))[0] == 0xFF  # WRITE_DAQ
    mode = 0x10 if timestamp else 0x00
    assert cro(0xE0, mode, 0, 0, event, 0, 1, 0)[0] == 0xFF       # SET_DAQ_LIST_MODE, prescaler 1
    assert cro(0xDE, 0x01, 0, 0)[0] == 0xFF                       # START_STOP_DAQ_LIST: start


def test_the_event_channels_fire_every_tick_every_1ms_and_every_10ms():
    for event, period in ((0, 1), (1, 2), (2, 20)):
        ecu = Ecu()
        cro = Cro(ecu)
        cro.connect_unlocked()
        start_daq(cro, [[cro.desc.item("tick")]], event)
        stamps, ticks = [], []
        for _ in range(200):
            for m in ecu.step():
                if m.arbitration_id == cro.desc.dto_id and m.data[0] == 0:  # PID 0: the list's ODT
                    stamps.append(struct.unpack("<I", m.data[1:5])[0])
                    ticks.append(struct.unpack("<I", m.data[5:9])[0])
        assert len(ticks) >= 200 // period - 1
        assert {b - a for a, b in zip(ticks, ticks[1:])} == {period}, event
        assert all(t % period == 0 for t in ticks)                      # at the runnable's rate
        assert [s - t for s, t in zip(stamps, ticks)] == [stamps[0] - ticks[0]] * len(ticks)  # timestamp = tick


def test_daq_values_equal_what_the_ecu_publishes_on_its_estimate_frames():
    """A DAQ list on the tick event through a whole in-process launch (its DTOs are frames of the
    session like any other): each sample equals that tick's VEHEST_DrivelineEst signals, exactly
    for the health, within the DBC's resolution (0.25 Nm) for the torques."""
    from vehest_can.sim.report import decode

    ecu = Ecu()
    cro = Cro(ecu)
    cro.connect_unlocked()
    names = ["tick", "app.drv.dkf[0].x[2]", "app.drv.dkf[0].x[3]", "app.drv.dkf[1].x[2]", "app.drv.dkf[1].x[3]",
             "app.drv.dkf[0].health", "app.drv.dkf[1].health"]
    items = [cro.desc.item(n) for n in names]
    start_daq(cro, [items], event=0)
    first = ecu.tick  # the session runs on from here (the commands took ticks)
    session = run_inprocess(powertrain_car(load_driveline_scenario("launch_2nd"), 1.0), ecu)
    est = decode(session, "VEHEST_DrivelineEst")
    fmt = "<" + "".join(C_TYPES[it.ctype][4] for it in items)
    dtos = session.frames[session.frames["id"] == cro.desc.dto_id]
    rows = [struct.unpack(fmt, bytes(f["data"][5:5 + struct.calcsize(fmt)])) for f in dtos if f["data"][0] == 0]
    # the START's answer took one tick's slot: at one sample per tick (the whole budget) the
    # stream runs one sample behind, so the first is from the tick before the session
    assert rows[0][0] == first - 1
    rows = rows[1:]
    assert len(rows) == len(session.truth) - 1  # one sample per tick, none lost
    cols = {"app.drv.dkf[0].x[2]": "DkfT_ShaftTorque", "app.drv.dkf[0].x[3]": "DkfT_RoadLoadErr",
            "app.drv.dkf[1].x[2]": "DkfS_ShaftTorque", "app.drv.dkf[1].x[3]": "DkfS_RoadLoadErr",
            "app.drv.dkf[0].health": "DkfT_Health", "app.drv.dkf[1].health": "DkfS_Health"}
    ticks = np.array([r[0] for r in rows]) - first  # the session's tick of each sample
    assert list(ticks) == list(range(len(rows)))
    moving = 0
    for name, sig in cols.items():
        daq = np.array([r[names.index(name)] for r in rows])
        frame = est[sig][ticks]
        if "health" in name:
            assert np.array_equal(daq, frame), name
        else:
            assert np.all(np.abs(daq - frame) <= 0.125 + 1e-9), (name, np.max(np.abs(daq - frame)))
            moving += np.ptp(daq) > 100.0
    assert moving >= 2  # the launch moves the torques: not a comparison of zeros


def test_at_most_one_xcp_frame_per_tick_and_dtos_carry_the_tick():
    """DAQ of 20 floating-point items on the tick event (4 DTOs per tick of 48 bytes) is more than the budget
    of one XCP frame per tick: the ECU never sends more, the queue overruns, whole samples are
    dropped and counted."""
    ecu = Ecu()
    cro = Cro(ecu)
    cro.connect_unlocked()
    desc = cro.desc
    doubles = [it for it in desc.measurements if it.ctype in ("double", "float")][:20]
    assert len(doubles) == 20
    per_odt = (desc.max_dto - 1) // 8
    odts = [doubles[i:i + per_odt] for i in range(0, len(doubles), per_odt)]
    start_daq(cro, odts, event=0, timestamp=False)
    per_tick = []
    for _ in range(400):
        per_tick.append(sum(m.arbitration_id == desc.dto_id for m in ecu.step()))
    assert max(per_tick) == 1 and sum(per_tick) == 400
    n = xcp_ecu.counters(ecu)
    assert n["dto_overrun"] > 0 and n["dto"] % len(odts) == 0  # whole samples or none
