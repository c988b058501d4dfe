"""XCP access control: the memory the slave exposes, seed & key with the user's key (delay,
lockout), and calibration that cannot be turned into an attack (safety classes, the ECU's safe
state), all as an attacker on the bus would try them: raw CRO frames into the firmware."""
from __future__ import annotations

import os
import struct

import can
import numpy as np
import pytest
from test_xcp_ecu import (
    ERR,
    ERR_ACCESS_DENIED,
    ERR_ACCESS_LOCKED,
    ERR_OUT_OF_RANGE,
    ERR_RESOURCE_TEMPORARY_NOT_ACCESSIBLE,
    ERR_WRITE_PROTECTED,
    KEY,
    Cro,
)

from vehest_can.bus.frames import to_message
from vehest_can.errors import ConfigError
from vehest_can.native import ffi, lib
from vehest_can.schema import read_toml
from vehest_can.systems.ecu import Ecu
from vehest_can.systems.roll.scenario import RollCar, roll_scenario_from_dict, roll_scenario_path
from vehest_can.xcp import ecu as xcp_ecu
from vehest_can.xcp import ecu_desc, keys

# ---- the memory: the description's measurements and the calibration segment, nothing else ----


def _slave_upload(ecu: Ecu, address: int, n: int) -> bytes | None:
    """SHORT_UPLOAD straight into the slave (no ECU tick: the whole address space in seconds)."""
    x = ffi.addressof(ecu.c.xcp, "slave")
    lib.vh_xcp_rx(x, bytes([0xF4, n, 0, 0]) + struct.pack("<I", address), 8, 0)
    f = ffi.new("vh_xcp_frame_t *")
    assert lib.vh_xcp_tx_pop(x, f) == 1
    data = bytes(f.data[0:f.len])
    return data[1:1 + n] if data[0] == 0xFF else None


@pytest.mark.slow
def test_upload_reads_the_described_measurements_and_calibration_only_over_the_whole_address_space():
    """Every region boundary +-1, every byte of the ECU instance's address window and a sweep of the
    32-bit space every 4 KiB (and the last bytes): what UPLOAD returns is exactly the described
    measurements' bytes and the calibration segment; no byte of the key (not in vh_ecu_t at all),
    of its key schedule or of any pointer is in what it returns."""
    ecu = Ecu()
    desc = xcp_ecu.enable(ecu, KEY)
    cro = Cro.__new__(Cro)
    cro.ecu, cro.desc, cro.other = ecu, desc, []
    assert cro(0xFF, 0)[0] == 0xFF  # CONNECT: UPLOAD needs no unlock (the standard allows that)
    described = set()
    for m in desc.measurements:
        described |= set(range(m.address, m.address + m.size))
    cal = set(range(desc.calibration_address, desc.calibration_address + ffi.sizeof("vh_ecu_cal_t")))
    size = ffi.sizeof("vh_ecu_t")
    readable, data = set(), bytearray()
    for a in range(desc.measurement_address - 16, desc.measurement_address + size + 16):  # byte by byte
        got = _slave_upload(ecu, a, 1)
        if got is not None:
            readable.add(a)
            data += got
    assert readable == described  # the described members, no other byte of vh_ecu_t
    edges = {a for m in desc.measurements for a in (m.address - 1, m.address, m.address + m.size - 1, m.address + m.size)}
    edges |= {desc.calibration_address - 1, desc.calibration_address, max(cal), max(cal) + 1}
    sweep = set(range(0, 1 << 32, 4096)) | {0xFFFFFFFF, 0xFFFFFFFC} | edges
    n_ok = 0
    for a in sorted(sweep):
        got = _slave_upload(ecu, a, 1)
        assert (got is not None) == (a in described or a in cal), hex(a)
        n_ok += got is not None
        if got is None and a + 4 <= 1 << 32:  # a 4-byte read reaching in from outside is refused too
            assert _slave_upload(ecu, a, 4) is None or {a, a + 1, a + 2, a + 3} <= described | cal
    # what a reader got: no key, no key schedule, no pointer (the ECU's, the key's, the regions')
    secrets_ = [KEY, bytes(ffi.buffer(xcp_ecu._KEYS[ecu]))[:32]]
    pointers = [int(ffi.cast("uintptr_t", p)) for p in (ecu.c, xcp_ecu._KEYS[ecu], ecu.c.xcp.regions[0].mem)]
    blob = bytes(data)
    for s in secrets_:
        assert s not in blob
    for p in pointers:
        assert struct.pack("<Q", p)[:6] not in blob
    pointer_members = [ffi.offsetof("vh_ecu_t", "secoc"), ffi.offsetof("vh_ecu_t", "xcp", "slave", "cfg", "key"),
                       ffi.offsetof("vh_ecu_t", "xcp", "regions")]
    assert not any(desc.measurement_address + o in readable for o in pointer_members)
    print(f"UPLOAD over the 32-bit space: {len(readable)} readable bytes of the {size}-byte ECU instance "
          f"(= the {len(desc.measurements)} measurements, {len(ecu_desc.regions(desc))} regions), "
          f"{len(sweep)} sweep/edge addresses ({n_ok} readable: measurements or calibration); "
          f"0 bytes of the key, its schedule or a pointer")


# ---- seed & key: the user's key, a growing delay, a lockout -------------------------------------

def test_wrong_keys_get_a_doubling_delay_then_a_lockout_and_the_session_stays():
    """Measured in ECU ticks: after each wrong key GET_SEED is refused
    (ERR_RESOURCE_TEMPORARY_NOT_ACCESSIBLE) for 1000, 2000, 4000, 8000 ticks (0.5, 1, 2, 4 s); the
    5th wrong key locks seed & key until restart (ERR_ACCESS_DENIED, even with the right key); the
    session stays throughout; a burst of wrong UNLOCKs is answered, not checked."""
    ecu = Ecu()
    cro = Cro(ecu)
    assert cro(0xFF, 0)[0] == 0xFF
    waits = []
    for attempt in range(1, 6):
        seed = cro(0xF8, 0, 1)
        assert seed[:2] == bytes([0xFF, 6])
        assert cro(0xF7, 6, *bytes(6))[:2] == bytes([ERR, ERR_ACCESS_LOCKED])  # wrong key
        assert ecu.c.xcp.slave.connected  # the session stays
        if attempt == 5:
            break
        t0 = int(ecu.c.xcp.ticks)
        while (r := cro(0xF8, 0, 1))[0] == ERR:
            assert r[1] == ERR_RESOURCE_TEMPORARY_NOT_ACCESSIBLE
            for _ in range(49):
                ecu.step()
        waits.append(int(ecu.c.xcp.ticks) - t0)
    # locked out: GET_SEED and UNLOCK refused, for good
    for _ in range(20000):
        ecu.step()
    assert cro(0xF8, 0, 1)[:2] == bytes([ERR, ERR_ACCESS_DENIED])
    assert cro(0xF7, 6, *bytes(6))[:2] == bytes([ERR, ERR_ACCESS_DENIED])
    n = xcp_ecu.counters(ecu)
    assert waits == [pytest.approx(w, abs=51) for w in (1000, 2000, 4000, 8000)]
    assert n["key_fail"] == 5 and n["unlock_lockout"] == 2 and ecu.c.xcp.slave.locked_out == 1
    # an attacker's burst: 2144 wrong keys all answered, 0 of them checked against the key
    for _ in range(2144):
        cro(0xF7, 6, *bytes(6))
    assert xcp_ecu.counters(ecu)["key_fail"] == 5
    assert xcp_ecu.read(ecu, "xcp.slave.locked_out") == 1  # a measurement the monitor can show
    print(f"wrong keys: delays {waits} ticks (x 0.5 ms), lockout after 5 wrong keys; a burst of 2144 more: "
          f"0 checked; counters {n['key_fail']} key_fail, {n['unlock_delayed']} delayed, "
          f"{xcp_ecu.counters(ecu)['unlock_lockout']} refused in lockout")


def test_a_foreign_connect_or_wrong_unlock_does_not_end_the_masters_session():
    ecu = Ecu()
    cro = Cro(ecu)
    cro.connect_unlocked()
    assert cro(0xFF, 0)[0] == 0xFF  # another node's CONNECT: the session and its unlock stay
    assert ecu.c.xcp.slave.locked == 0
    assert cro(0xF7, 6, *bytes(6))[:2] == bytes([ERR, 0x29])  # a blind UNLOCK without a seed: ERR_SEQUENCE
    assert ecu.c.xcp.slave.connected and ecu.c.xcp.slave.locked == 0
    a = cro.desc.item("cal.app.drv.we_min").address
    assert cro.download(a, struct.pack("<d", 41.0))[0] == 0xFF  # the master goes on


def test_the_key_the_firmware_wants_is_the_cmac_of_the_users_key():
    """The C (vh_xcp_key) and cryptography's CMAC agree; a key for CAL/PAG does not unlock DAQ;
    another user's key does not unlock."""
    seed = os.urandom(6)
    for res in (1, 4):
        assert xcp_ecu.firmware_key_for(seed, res, KEY) == keys.key_for(seed, res, KEY)
    assert keys.key_for(seed, 1, KEY) != keys.key_for(seed, 4, KEY)
    ecu = Ecu()
    cro = Cro(ecu)
    assert cro(0xFF, 0)[0] == 0xFF
    s = cro(0xF8, 0, 4)
    assert cro(0xF7, 6, *keys.key_for(s[2:8], 1, KEY))[:2] == bytes([ERR, ERR_ACCESS_LOCKED])
    for _ in range(1000):
        ecu.step()
    s = cro(0xF8, 0, 1)
    assert cro(0xF7, 6, *keys.key_for(s[2:8], 1, keys.DEV_KEY))[:2] == bytes([ERR, ERR_ACCESS_LOCKED])


def test_keygen_writes_mode_600_and_bad_key_files_are_clear_errors(tmp_path, capsys):
    from vehest_can.cli import main

    f = tmp_path / "xcp.key"
    assert main(["xcp", "keygen", str(f)]) == 0
    assert f.stat().st_mode & 0o777 == 0o600 and len(keys.load_key(f)) == 16
    assert main(["xcp", "keygen", str(f)]) == 1
    assert "exists; not overwritten" in capsys.readouterr().err
    f.chmod(0o640)
    with pytest.raises(ConfigError, match="too open"):
        keys.load_key(f)
    bad = tmp_path / "bad.key"
    for text, msg in (('[xcp]\nkey = "abc"\n', "32 hexadecimal digits"), ("[keys]\nX = 1\n", "unknown key"),
                      ("", "needs an \\[xcp\\] table"), ("[xcp\n", "bad.key")):
        bad.unlink(missing_ok=True)
        bad.write_text(text)
        bad.chmod(0o600)
        with pytest.raises(ConfigError, match=msg):
            keys.load_key(bad)
    assert main(["daemon", "--xcp", "on", "--duration", "0.1"]) == 1
    assert "needs a seed & key key" in capsys.readouterr().err
    assert main(["daemon", "--xcp-key", str(f), "--duration", "0.1"]) == 1
    assert "needs the XCP slave (--xcp on)" in capsys.readouterr().err


def test_xcp_is_off_unless_turned_on():
    import argparse

    parser = argparse.ArgumentParser()
    xcp_ecu.add_arguments(parser)
    ecu = Ecu()
    assert xcp_ecu.from_args(parser.parse_args([]), ecu) is None and not xcp_ecu.enabled(ecu)
    ecu.rx(can.Message(arbitration_id=0x7E0, is_extended_id=False, is_fd=True, data=bytes([0xFF, 0])))
    assert not [m for m in ecu.step() if m.arbitration_id == 0x7E1]  # no answer
    with pytest.raises(ConfigError, match="16-byte"):
        xcp_ecu.enable(Ecu(), b"short")


def test_with_a_bus_of_its_own_the_slave_listens_there_only():
    ecu = Ecu()
    desc = xcp_ecu.enable(ecu, KEY, own_bus=True)
    connect = can.Message(arbitration_id=desc.cro_id, is_extended_id=False, is_fd=True, data=bytes([0xFF, 0]))
    ecu.rx(connect)  # on the vehicle bus
    assert not [m for m in ecu.step() if m.arbitration_id == desc.dto_id]
    assert xcp_ecu.counters(ecu)["cro_foreign"] == 1 and not ecu.c.xcp.slave.connected
    xcp_ecu.rx_own(ecu, connect)  # on the XCP bus
    assert [bytes(m.data)[0] for m in ecu.step() if m.arbitration_id == desc.dto_id] == [0xFF]
    xcp_ecu.rx_own(ecu, can.Message(arbitration_id=0x100, data=bytes(8)))  # not input of any system there
    assert ecu.counters()["unknown_id"] == 0


# ---- calibration that cannot be turned into an attack -----------------------------------------

#: the hostile set: in range, each would weaken a monitor or the controller while the car drives
HOSTILE = [("cal.rx_burst_frames", "<B", 16), ("cal.app.roll.ukf.nis_max", "<d", 1.0e4),
           ("cal.app.roll.smc.front_share", "<d", 1.0), ("cal.app.roll.smc.k", "<d", 100.0),
           ("cal.app.roll.smc.lambda", "<d", 100.0), ("cal.app.roll.smc.m_max_r", "<d", 1.0),
           ("cal.app.roll.smc.ref_frac", "<d", 1.0), ("cal.app.roll.ukf.phi_max", "<d", 0.5),
           ("cal.app.drv.dkf[0].p_max", "<d", 1.0e12)]
#: out of range now (they switched a check off): refused whatever the state
SWITCHED_OFF = [("cal.rx_burst_frames", "<B", 0), ("cal.app.roll.ukf.nis_max", "<d", 0.0),
                ("cal.app.roll.ukf.r", "<d", 100.0), ("cal.app.drv.dkf[0].r", "<d", 1.0e9),
                ("cal.app.roll.stuck_samples", "<B", 255)]


class CarCro(Cro):
    """CRO frames into an ECU that a roll car drives in-process, one car tick per command."""

    def __init__(self, ecu: Ecu, car, **kw):
        super().__init__(ecu, **kw)
        self.car, self.k = car, 0
        car.reset()

    def tick(self) -> list:
        for f in self.car.tick(self.k):
            self.ecu.rx_frame(ffi.addressof(f))
        out = []
        for f in self.ecu.step_frames():
            self.car.rx(ffi.addressof(f))  # the roll commands close the loop
            out.append(to_message(f, 0.0))
        self.k += 1
        return out

    def run_to(self, k: int) -> None:
        while self.k < k:
            self.tick()

    def __call__(self, *data: int) -> bytes:
        self.ecu.rx(can.Message(arbitration_id=self.desc.cro_id, is_extended_id=False, is_fd=self.desc.fd,
                                data=bytes(data)))
        res = [m for m in self.tick() if m.arbitration_id == self.desc.dto_id]
        assert len(res) == 1, res
        return bytes(res[0].data)


def _roll_car(name: str = "roll_paper_72kph_active", **over) -> RollCar:
    path = roll_scenario_path(name)
    doc = read_toml(path)
    doc.update(over)
    return RollCar(roll_scenario_from_dict(doc, path))


def _try_all(cro: Cro, rows) -> list[bytes]:
    return [cro.download(cro.desc.item(name).address, struct.pack(fmt, v))[:2] for name, fmt, v in rows]


def test_hostile_calibration_is_refused_while_driving_and_accepted_in_the_safe_state():
    """72 km/h, 5 deg steer, roll control active (the ECU's own decision: not safe): every hostile
    in-range value ERR_WRITE_PROTECTED, counted, nothing changed in the running controller; a tuning
    value still goes in. Standstill with roll passive, and the calibration mode at speed (roll held
    passive): every one accepted and committed. Values that switch a check off: out of range always."""
    driving = CarCro(Ecu(), _roll_car())
    driving.run_to(6000)  # 3 s: the steer ramp is done, the controller acts
    assert int(driving.ecu.c.xcp.safe) == 0 and driving.ecu.c.app.roll.smc.fade == 1.0
    driving.connect_unlocked()
    before = bytes(ffi.buffer(ffi.addressof(driving.ecu.c.xcp, "page")))
    refused = _try_all(driving, HOSTILE)
    assert refused == [bytes([ERR, ERR_WRITE_PROTECTED])] * len(HOSTILE)
    assert bytes(ffi.buffer(ffi.addressof(driving.ecu.c.xcp, "page"))) == before  # nothing reached the ECU
    assert driving.ecu.c.app.roll.smc.front_share == pytest.approx(0.5705777976983007)
    assert xcp_ecu.counters(driving.ecu)["cal_unsafe"] == len(HOSTILE)
    # switched-off values: safety-relevant ones are write protected first (not now, whatever the value)
    assert all(r[0] == ERR and r[1] in (ERR_WRITE_PROTECTED, ERR_OUT_OF_RANGE) for r in _try_all(driving, SWITCHED_OFF))
    assert driving.download(driving.desc.item("cal.app.drv.we_min").address, struct.pack("<d", 41.0))[0] == 0xFF  # tuning
    # an ECU page switch would swap safety-relevant values at once: refused too
    assert driving(0xEB, 0x01, 0, 1)[:2] == bytes([ERR, ERR_WRITE_PROTECTED])

    still = CarCro(Ecu(), _roll_car("roll_paper_72kph_passive", initial_speed_kmh=0.0,
                                    driver={"steer_deg": [[0.0, 0.0]]}, duration_s=2.0))
    still.run_to(1000)
    assert int(still.ecu.c.xcp.safe) == 1  # standstill, roll passive
    calmode = CarCro(Ecu(), _roll_car(), cal_mode=True)
    calmode.run_to(6000)  # at speed, in the steer: the roll actuators held passive
    assert int(calmode.ecu.c.xcp.safe) == 1 and calmode.ecu.c.app.roll.smc.fade == 0.0
    for cro in (still, calmode):
        cro.connect_unlocked()
        assert [r[0] for r in _try_all(cro, HOSTILE)] == [0xFF] * len(HOSTILE)
        cro.tick()
        assert cro.ecu.c.app.roll.smc.front_share == 1.0 and cro.ecu.c.rx_burst_frames == 16
        assert cro.ecu.c.app.roll.smc.ref_frac == 1.0 and cro.ecu.c.app.roll.cfg.ukf.nis_max == 1.0e4
        assert _try_all(cro, SWITCHED_OFF) == [bytes([ERR, ERR_OUT_OF_RANGE])] * len(SWITCHED_OFF)
        assert xcp_ecu.counters(cro.ecu)["cal_unsafe"] == 0
    moments = np.array([calmode.ecu.c.app.roll.smc.m_f, calmode.ecu.c.app.roll.smc.m_r])
    assert np.all(moments == 0.0)  # calibration mode: passive throughout
    print(f"hostile set ({len(HOSTILE)} writes): driving 72 km/h active: {len(HOSTILE)} ERR_WRITE_PROTECTED "
          f"(cal_unsafe {len(HOSTILE)}); standstill + passive and calibration mode: all accepted; switched-off "
          f"values ({len(SWITCHED_OFF)}): ERR_OUT_OF_RANGE in every state")


def test_a_safety_write_left_open_is_dropped_when_the_safe_state_ends():
    """Six bytes of a double written in the safe state (a fresh ECU: nothing heard, roll passive),
    the commit due after the state ended: dropped (cal_unsafe), the working page takes the ECU's
    value back; a tuning value left open the same way is not held back by the state."""
    ecu = Ecu()
    cro = Cro(ecu)
    cro.connect_unlocked()
    assert int(ecu.c.xcp.safe) == 1
    phi = cro.desc.item("cal.app.roll.ukf.phi_max")
    q = cro.desc.item("cal.app.roll.ukf.q")
    assert cro.download(phi.address, struct.pack("<d", 0.4)[:6])[0] == 0xFF  # part-way: due after open_ticks
    assert cro.download(q.address, struct.pack("<d", 1e-3)[:6])[0] == 0xFF
    ecu.c.xcp.heard = 0xFF  # every speed source heard once and silent now: standstill unknown, not safe
    for _ in range(300):
        ecu.step()
    assert int(ecu.c.xcp.safe) == 0
    assert xcp_ecu.counters(ecu)["cal_unsafe"] == 1  # phi_max dropped; q (tuning) committed or, half a double, dropped
    assert xcp_ecu.counters(ecu)["cal_commits"] + xcp_ecu.counters(ecu)["cal_dropped"] == 1
    assert xcp_ecu.read(ecu, "cal.app.roll.ukf.phi_max", "work") == xcp_ecu.read(ecu, "cal.app.roll.ukf.phi_max") == 0.3
    assert cro.download(phi.address, struct.pack("<d", 0.4))[:2] == bytes([ERR, ERR_WRITE_PROTECTED])
