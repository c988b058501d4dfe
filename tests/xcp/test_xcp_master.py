"""pyxcp as the master: identification, status, memory access, seed & key, calibration pages."""
from __future__ import annotations

import struct

import pytest

types = pytest.importorskip("pyxcp.types")

ERR = types.XcpResponseError


def code(excinfo) -> int:
    c = excinfo.value.get_error_code()
    return getattr(c, "intvalue", c)


def test_connect_reports_the_configuration(rig):
    r = rig.master.connect()
    assert r.maxCto == 8 and r.maxDto == 8
    assert r.resource.calpag and r.resource.daq and not r.resource.pgm
    assert r.commModeBasic.byteOrder == types.ByteOrder.INTEL
    assert r.commModeBasic.optional
    info = rig.master.getCommModeInfo()
    assert info.commModeOptional.masterBlockMode is False


def test_get_id_and_status(rig):
    rig.connect()
    assert rig.master.identifier(types.XcpGetIdType.ASCII_TEXT) == "vehest-can ECU XCP slave"
    assert rig.master.identifier(types.XcpGetIdType.FILENAME) == rig.desc.name
    st = rig.master.getStatus()
    assert st.resourceProtectionStatus.calpag and st.resourceProtectionStatus.daq
    assert not st.sessionStatus.daqRunning


def f32(v):
    return struct.unpack("<f", struct.pack("<f", v))[0]


def test_upload_reads_measurements_and_the_calibration_page(rig):
    rig.connect()
    rig.slave.write_measurement("dkf_x_torque", 123.25)
    rig.slave.write_measurement("ecu_tick", 0xA1B2C3D4)
    m = rig.desc.item("dkf_x_torque")
    assert struct.unpack("<f", rig.master.shortUpload(4, m.address))[0] == 123.25
    rig.master.setMta(rig.desc.item("ecu_tick").address)
    assert rig.master.upload(4) == struct.pack("<I", 0xA1B2C3D4)
    g = rig.desc.item("skf_gain")
    rig.master.setMta(g.address)
    raw = rig.master.fetch(g.size)  # 64 bytes in UPLOADs of MAX_CTO - 1
    assert list(struct.unpack("<16f", raw)) == rig.slave.read("skf_gain", "work")


def test_mta_outside_described_memory_is_refused_and_counted(rig):
    rig.connect()
    before = rig.slave.counters()["err_access"]
    outside = [0x0, rig.desc.measurement_address - 1, rig.desc.measurement_address + rig.desc.measurement_size - 2,
               rig.desc.calibration_address + rig.desc.calibration_size, 0xFFFFFFFC]
    for a in outside:
        with pytest.raises(ERR) as e:
            rig.master.shortUpload(4, a)
        assert code(e) == 0x24  # ERR_ACCESS_DENIED
    rig.master.cond_unlock("calpag")
    m = rig.desc.item("dkf_x_torque")  # a measurement: readable, never writable
    rig.master.setMta(m.address)
    with pytest.raises(ERR) as e:
        rig.master.download(struct.pack("<f", 1.0))
    assert code(e) == 0x24
    assert rig.slave.counters()["err_access"] == before + len(outside) + 1
    assert rig.slave.read("dkf_x_torque") == 0.0


def test_write_without_seed_and_key_is_refused(rig):
    rig.connect()
    r = rig.desc.item("dkf_r_torque")
    rig.master.setMta(r.address)
    with pytest.raises(ERR) as e:
        rig.master.download(struct.pack("<f", 100.0))
    assert code(e) == 0x25  # ERR_ACCESS_LOCKED
    with pytest.raises(ERR):
        rig.master.setCalPage(0x83, 0, 1)
    assert rig.slave.counters()["err_locked"] == 2
    assert rig.slave.read("dkf_r_torque", "work") == 64.0


def test_a_wrong_key_is_refused_counted_delayed_and_the_session_stays(rig):
    """A wrong key: ERR_ACCESS_LOCKED, counted, the session kept (a guessing node cannot end the
    master's); seed & key then waits unlock_delay_ticks (ERR_RESOURCE_TEMPORARY_NOT_ACCESSIBLE),
    after which pyxcp's seed & key with the key file's key unlocks."""
    rig.connect()
    seed = rig.master.getSeed(0, 0x01)
    assert seed.length == 6
    with pytest.raises(ERR) as e:
        rig.master.unlock(6, [0, 0, 0, 0, 0, 0])
    assert code(e) == 0x25
    assert rig.slave.counters()["key_fail"] == 1
    assert rig.slave.x.connected and rig.slave.x.fail_streak == 1
    with pytest.raises(ERR) as e:
        rig.master.getSeed(0, 0x01)
    assert code(e) == 0x33  # in the delay
    assert rig.slave.counters()["unlock_delayed"] == 1
    rig.bridge.advance(1000)  # the delay: 1000 ticks after the first wrong key
    rig.master.cond_unlock("calpag")  # the right key, computed from a fresh seed
    assert not rig.master.getStatus().resourceProtectionStatus.calpag
    assert rig.slave.x.fail_streak == 0


def test_download_lands_at_the_next_tick_boundary(rig):
    rig.connect()
    rig.master.cond_unlock("calpag")
    rig.bridge.advance(3)
    rig.download("dkf_r_torque", [100.0])
    # written to the working page (the master reads it back) but the ECU still sees the old value
    rig.master.setMta(rig.desc.item("dkf_r_torque").address)
    assert struct.unpack("<f", rig.master.upload(4))[0] == 100.0
    assert rig.slave.read("dkf_r_torque") == 64.0
    rig.bridge.advance(1)
    assert rig.slave.read("dkf_r_torque") == 100.0
    assert rig.slave.counters()["cal_writes"] == 1 and rig.slave.counters()["cal_commits"] == 1


def test_a_matrix_reaches_the_ecu_whole(rig):
    """64 bytes take 11 DOWNLOADs over classic CAN; ticks in between never show a mix."""
    rig.connect()
    rig.master.cond_unlock("calpag")
    g = rig.desc.item("skf_gain")
    new = [float(i) / 4 for i in range(16)]
    blob = struct.pack("<16f", *new)
    old = rig.slave.read("skf_gain")
    seen = []
    rig.master.setMta(g.address)
    for i in range(0, len(blob), 6):
        rig.master.download(blob[i:i + 6])
        rig.bridge.advance(1)
        seen.append(rig.slave.read("skf_gain"))
    assert all(s == old for s in seen[:-1]) and seen[-1] == new


def test_out_of_range_write_is_refused_and_counted(rig):
    rig.connect()
    rig.master.cond_unlock("calpag")
    for name, bad in [("dkf_r_torque", 10000.5), ("dkf_r_torque", -1.0), ("dkf_r_torque", float("nan")),
                      ("skf_gain", 10.5), ("rx_timeout_ticks", 1), ("torque_offset", 401)]:
        item = rig.desc.item(name)
        rig.master.setMta(item.address)
        fmt = {"float": "<f", "uint16_t": "<H", "int16_t": "<h"}[item.ctype]
        with pytest.raises(ERR) as e:
            rig.master.download(struct.pack(fmt, bad))
        assert code(e) == 0x22  # ERR_OUT_OF_RANGE
    assert rig.slave.counters()["err_range"] == 6
    # the limits themselves are accepted (torque_offset: 100 Nm = 400 raw at 0.25 Nm/LSB)
    rig.download("dkf_r_torque", [10000.0])
    rig.download("torque_offset", [400])
    rig.bridge.advance(1)
    assert rig.slave.read("dkf_r_torque") == 10000.0 and rig.slave.read("torque_offset") == 400


def test_calibration_pages(rig):
    rig.connect()
    rig.master.cond_unlock("calpag")
    assert rig.master.getCalPage(0x01, 0) == 0 and rig.master.getCalPage(0x02, 0) == 0
    rig.download("dkf_r_torque", [200.0])
    rig.bridge.advance(1)
    assert rig.slave.read("dkf_r_torque") == 200.0
    # the master looks at the reference page: read-only, the original value
    rig.master.setCalPage(0x02, 0, 1)
    r = rig.desc.item("dkf_r_torque")
    assert struct.unpack("<f", rig.master.shortUpload(4, r.address))[0] == 64.0
    rig.master.setMta(r.address)
    with pytest.raises(ERR) as e:
        rig.master.download(struct.pack("<f", 1.0))
    assert code(e) == 0x23  # ERR_WRITE_PROTECTED
    # the ECU switches to the reference page at the next tick, and back
    rig.master.setCalPage(0x01, 0, 1)
    assert rig.slave.read("dkf_r_torque") == 200.0
    rig.bridge.advance(1)
    assert rig.slave.read("dkf_r_torque") == 64.0
    rig.master.setCalPage(0x83, 0, 0)  # ALL segments, ECU and XCP
    rig.bridge.advance(1)
    assert rig.slave.read("dkf_r_torque") == 200.0
    with pytest.raises(ERR):
        rig.master.setCalPage(0x03, 0, 2)  # no page 2


def test_daq_info_names_the_ecu_event_channels(rig):
    rig.connect()
    info = rig.master.getDaqInfo(include_event_lists=True)
    assert info["processor"]["properties"]["configType"] == "DYNAMIC"
    assert info["processor"]["maxDaq"] == 8
    assert info["resolution"]["timestampTicks"] == 500
    ev = info["channels"]
    assert [e["name"] for e in ev] == ["tick", "1ms", "10ms"]
    assert [(e["cycle"], e["unit"]) for e in ev] == [(50, "EVENT_CHANNEL_TIME_UNIT_10US"),
                                                      (100, "EVENT_CHANNEL_TIME_UNIT_10US"),
                                                      (100, "EVENT_CHANNEL_TIME_UNIT_100US")]


def test_can_fd_short_download_and_a_matrix_in_two_frames(make_rig):
    import tomllib

    from xcp_demo import DEMO

    from vehest_can.xcp.description import from_dict
    d = tomllib.loads(DEMO.read_text())
    d["xcp"].update(fd=True, max_cto=64, max_dto=64)
    rig = make_rig(from_dict(d))
    r = rig.connect()
    assert r.maxCto == 64 and r.maxDto == 64
    rig.master.cond_unlock("calpag")
    item = rig.desc.item("dkf_r_torque")
    rig.master.shortDownload(item.address, 0, struct.pack("<f", 42.0))  # 8-byte header + data
    g = rig.desc.item("skf_gain")
    new = [float(i) / 2 for i in range(-8, 8)]
    blob = struct.pack("<16f", *new)
    rig.master.setMta(g.address)
    rig.master.download(blob[:62])  # MAX_CTO - 2 bytes in one frame: the matrix is still open
    rig.bridge.advance(1)
    assert rig.slave.read("skf_gain") != new
    rig.master.download(blob[62:])
    rig.bridge.advance(1)
    assert rig.slave.read("skf_gain") == new and rig.slave.read("dkf_r_torque") == 42.0
    assert struct.unpack("<16f", rig.master.shortUpload(63, g.address)[:63] + b"\0")[:15] == tuple(new[:15])
