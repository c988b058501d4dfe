"""Bad input straight into the C slave: random CROs, DAQ over its limits, sequence errors.

The master here is independent of the slave's code: frames are built from the ASAM MCD-1 XCP
command codes in this file, and the answers are checked against the standard's packet format.
"""
from __future__ import annotations

import math
import struct
import tomllib

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from xcp_demo import DEMO, Slave  # noqa: E402

from vehest_can.xcp import key_for, load
from vehest_can.xcp.description import from_dict, raw_limits_for_c
from vehest_can.xcp.keys import SEED_LEN

DESC = load(DEMO)
FD_DESC = from_dict({**tomllib.loads(DEMO.read_text()),
                     "xcp": {**tomllib.loads(DEMO.read_text())["xcp"], "fd": True, "max_cto": 64, "max_dto": 64}})
KEY = bytes.fromhex("2b7e151628aed2a6abf7158809cf4f3c")  # RFC 4493's test key
KNOWN = [0xFF, 0xFE, 0xFD, 0xFC, 0xFB, 0xFA, 0xF8, 0xF7, 0xF6, 0xF5, 0xF4, 0xF0, 0xED, 0xEB, 0xEA, 0xE9,
         0xE3, 0xE2, 0xE1, 0xE0, 0xDF, 0xDE, 0xDD, 0xDC, 0xDA, 0xD9, 0xD7, 0xD6, 0xD5, 0xD4, 0xD3]
ERROR_CODES = {0x00, 0x10, 0x11, 0x12, 0x20, 0x21, 0x22, 0x23, 0x24, 0x25, 0x26, 0x27, 0x28, 0x29, 0x2A,
               0x30, 0x31, 0x32}
CONNECT = bytes([0xFF, 0x00])


def answer(s: Slave, cro: bytes) -> bytes | None:
    s.rx(cro)
    frames = s.frames()
    assert len(frames) <= 1, "one CRO, at most one answer (no DAQ without events)"
    return frames[0].data if frames else None


def unlocked(desc=DESC, **kw) -> Slave:
    s = Slave(desc, key=KEY, **kw)
    assert answer(s, CONNECT)[0] == 0xFF
    for res in (0x01, 0x04):
        seed = answer(s, bytes([0xF8, 0x00, res]))  # GET_SEED
        assert seed[0] == 0xFF and seed[1] == SEED_LEN
        assert answer(s, bytes([0xF7, SEED_LEN]) + key_for(seed[2:2 + SEED_LEN], res, KEY))[0] == 0xFF  # UNLOCK
    return s


def memory(s: Slave) -> tuple[bytes, bytes, bytes]:
    from vehest_can.native import ffi
    return (bytes(ffi.buffer(s.measurements)), bytes(ffi.buffer(s.cal_ref)), bytes(ffi.buffer(s.cal_work)))


def check_limits(s: Slave) -> None:
    """Every characteristic the application sees (the ECU page) is within its limits. (The working
    page may hold an element the master has written only part of: it is checked when complete.)"""
    for c in s.desc.characteristics:
        lo, hi = raw_limits_for_c(c)
        for page in ("ecu",):
            v = s.read(c.name, page)
            for x in (v if isinstance(v, list) else [v]):
                assert not math.isnan(x) and lo <= x <= hi, (c.name, page, x)


def well_formed(resp: bytes, s: Slave) -> None:
    assert 1 <= len(resp) <= s.desc.max_cto
    if s.desc.fd and len(resp) > 8:
        assert len(resp) in (12, 16, 20, 24, 32, 48, 64)
    assert resp[0] in (0xFF, 0xFE)
    if resp[0] == 0xFE:
        assert len(resp) >= 2 and resp[1] in ERROR_CODES


cro = st.one_of(
    st.binary(min_size=0, max_size=12),
    st.tuples(st.sampled_from(KNOWN), st.binary(min_size=0, max_size=9)).map(lambda t: bytes([t[0]]) + t[1]),
    st.tuples(st.sampled_from(KNOWN), st.binary(min_size=0, max_size=66)).map(lambda t: bytes([t[0]]) + t[1]),
)
variant = st.sampled_from([(DESC, False), (DESC, True), (FD_DESC, False)])  # classic, classic padded, FD


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(cro, min_size=1, max_size=40), st.booleans(), variant)
def test_random_cros_never_crash_and_always_answer_well(cros, unlock, var):
    desc, pad8 = var
    s = unlocked(desc, pad8=pad8) if unlock else Slave(desc, key=KEY, pad8=pad8)
    meas0, ref0, _ = memory(s)
    for i, c in enumerate(cros):
        was_connected = s.x.connected
        n0 = s.counters()
        resp = answer(s, c)
        n1 = s.counters()
        assert n1["cro"] == n0["cro"] + 1
        if not was_connected and c[:1] != b"\xFF":
            assert resp is None and n1["ignored"] == n0["ignored"] + 1  # ASAM: only CONNECT is answered
            continue
        assert resp is not None
        well_formed(resp, s)
        is_err = resp[0] == 0xFE and resp[1] != 0x00  # ERR_CMD_SYNCH is SYNCH's normal answer
        assert n1["err"] == n0["err"] + is_err
        s.tick(i + 1)
        s.event(0)
        s.frames()  # DTOs of whatever list the random bytes set up
    meas1, ref1, work1 = memory(s)
    assert meas1 == meas0 and ref1 == ref0  # measurements and the reference page are never written
    check_limits(s)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 7))
def test_upload_anywhere_is_either_described_memory_or_access_denied(address, n):
    s = Slave(DESC, key=KEY)
    answer(s, CONNECT)
    resp = answer(s, bytes([0xF4, n, 0, 0]) + struct.pack("<I", address))  # SHORT_UPLOAD
    inside = any(lo <= address and address + n <= lo + size for lo, size in
                 [(DESC.measurement_address, DESC.measurement_size),
                  (DESC.calibration_address, DESC.calibration_size)])
    if inside:
        assert resp[0] == 0xFF and len(resp) == 1 + n
    else:
        assert resp == bytes([0xFE, 0x24]) and s.counters()["err_access"] == 1


@settings(max_examples=200, deadline=None)
@given(st.integers(DESC.calibration_address - 8, DESC.calibration_address + DESC.calibration_size + 8),
       st.binary(min_size=1, max_size=6))
def test_download_anywhere_changes_only_characteristics_within_limits(address, data):
    s = unlocked()
    meas0, ref0, work0 = memory(s)
    answer(s, bytes([0xF6, 0, 0, 0]) + struct.pack("<I", address))  # SET_MTA
    resp = answer(s, bytes([0xF0, len(data)]) + data)  # DOWNLOAD
    well_formed(resp, s)
    meas1, ref1, work1 = memory(s)
    assert meas1 == meas0 and ref1 == ref0
    if resp[0] == 0xFE:
        assert work1 == work0 and resp[1] in (0x22, 0x24)
    else:
        assert work1 != work0 or data == work0[address - DESC.calibration_address:][:len(data)]
    s.tick(1)
    check_limits(s)


def test_daq_over_the_limits_is_refused_and_counted():
    s = unlocked()
    assert answer(s, bytes([0xD5, 0, 1, 0])) == bytes([0xFE, 0x29])  # ALLOC_DAQ before FREE_DAQ: ERR_SEQUENCE
    assert answer(s, bytes([0xD6])) == b"\xFF"  # FREE_DAQ
    assert answer(s, bytes([0xD5, 0, 9, 0])) == bytes([0xFE, 0x30])  # 9 lists > 8: ERR_MEMORY_OVERFLOW
    assert answer(s, bytes([0xD5, 0, 2, 0])) == b"\xFF"
    assert answer(s, bytes([0xD4, 0, 0, 0, 65])) == bytes([0xFE, 0x30])  # 65 ODTs > 64
    assert answer(s, bytes([0xD4, 0, 5, 0, 1])) == bytes([0xFE, 0x22])  # no list 5
    assert answer(s, bytes([0xD4, 0, 0, 0, 2])) == b"\xFF"
    assert answer(s, bytes([0xD4, 0, 0, 0, 2])) == bytes([0xFE, 0x29])  # once per list
    assert answer(s, bytes([0xD3, 0, 0, 0, 0, 200])) == b"\xFF"
    assert answer(s, bytes([0xD3, 0, 0, 0, 1, 57])) == bytes([0xFE, 0x30])  # 257 entries > 256
    assert answer(s, bytes([0xD4, 0, 1, 0, 1])) == bytes([0xFE, 0x29])  # ALLOC_ODT after ALLOC_ODT_ENTRY
    assert answer(s, bytes([0xD3, 0, 0, 0, 1, 2])) == b"\xFF"
    # an entry outside DAQ memory, an ODT over one DTO, a list with an entry left empty
    assert answer(s, bytes([0xE2, 0, 0, 0, 1, 0])) == b"\xFF"  # SET_DAQ_PTR list 0, ODT 1, entry 0
    assert answer(s, bytes([0xE1, 0xFF, 4, 0]) + struct.pack("<I", 0x1234)) == bytes([0xFE, 0x24])
    m = DESC.measurement_address
    assert answer(s, bytes([0xE1, 0xFF, 4, 0]) + struct.pack("<I", m)) == b"\xFF"
    assert answer(s, bytes([0xE1, 0xFF, 4, 0]) + struct.pack("<I", m + 4)) == bytes([0xFE, 0x2A])  # 8 > 7 bytes
    assert answer(s, bytes([0xDE, 2, 0, 0])) == bytes([0xFE, 0x2A])  # START_STOP_DAQ_LIST: ODT 0 empty
    assert answer(s, bytes([0xE0, 0x02, 0, 0, 0, 0, 1, 0])) == bytes([0xFE, 0x27])  # STIM: not supported
    assert answer(s, bytes([0xE0, 0x00, 0, 0, 9, 0, 1, 0])) == bytes([0xFE, 0x22])  # no event 9
    c = s.counters()
    assert (c["err_daq"], c["err_access"], c["err_range"], c["err_other"]) == (8, 1, 2, 1)


def test_a_running_list_cannot_be_rewritten():
    """WRITE_DAQ through a cursor set before its list started is ERR_DAQ_ACTIVE: a running list's
    ODTs are fixed, so a timestamped ODT 0 cannot outgrow MAX_DTO (fuzzer input
    tests/fuzz/regressions/xcp_write_running_list: a 36-byte entry made a 49-byte DTO over 48)."""
    desc = from_dict({**tomllib.loads(DEMO.read_text()),
                      "xcp": {**tomllib.loads(DEMO.read_text())["xcp"], "fd": True, "max_cto": 8, "max_dto": 48}})
    s = unlocked(desc)
    m = struct.pack("<I", desc.measurement_address)
    for cro in ([0xD6], [0xD5, 0, 1, 0], [0xD4, 0, 0, 0, 1], [0xD3, 0, 0, 0, 0, 2],
                [0xE0, 0x10, 0, 0, 0, 0, 1, 0],                     # SET_DAQ_LIST_MODE: timestamp, event 0
                [0xE2, 0, 0, 0, 0, 0], [0xE1, 0xFF, 4, 0, *m], [0xE1, 0xFF, 4, 0, *m],
                [0xE2, 0, 0, 0, 0, 1],                               # the cursor back on entry 1
                [0xDE, 1, 0, 0]):                                    # START_STOP_DAQ_LIST: start list 0
        assert answer(s, bytes(cro))[0] == 0xFF, cro
    assert answer(s, bytes([0xE1, 0xFF, 36, 0, *m])) == bytes([0xFE, 0x11])  # ERR_DAQ_ACTIVE
    assert answer(s, bytes([0xE2, 0, 0, 0, 0, 0])) == bytes([0xFE, 0x11])
    s.event(0)
    dtos = s.frames()
    assert len(dtos) == 1 and len(dtos[0].data) <= 48 and len(dtos[0].data) >= 1 + 4 + 8
    assert answer(s, bytes([0xDE, 0, 0, 0]))[0] == 0xFF                   # stopped: the list can change again
    assert answer(s, bytes([0xE1, 0xFF, 40, 0, *m])) == b"\xFF"             # 4 + 40 bytes fit an ODT ...
    assert answer(s, bytes([0xDE, 1, 0, 0])) == bytes([0xFE, 0x2A])        # ... but not with the timestamp


def test_daq_commands_need_the_daq_resource():
    s = Slave(DESC, key=KEY)
    answer(s, CONNECT)
    for cro in ([0xD6], [0xD5, 0, 1, 0], [0xDD, 1], [0xE2, 0, 0, 0, 0, 0]):
        assert answer(s, bytes(cro)) == bytes([0xFE, 0x25])
    assert answer(s, bytes([0xDA]))[0] == 0xFF  # GET_DAQ_PROCESSOR_INFO is not protected
    assert s.counters()["err_locked"] == 4


def test_short_and_unknown_cros():
    s = Slave(DESC, key=KEY)
    assert answer(s, b"") is None and answer(s, b"\xFD") is None  # not connected: silence
    answer(s, CONNECT)
    assert answer(s, b"") == bytes([0xFE, 0x21])
    assert answer(s, b"\xF6\x00\x00") == bytes([0xFE, 0x21])  # SET_MTA needs 8 bytes
    assert answer(s, b"\xF0\x05\x01") == bytes([0xFE, 0x21])  # DOWNLOAD of 5 with 1 byte of data
    assert answer(s, b"\x00") == bytes([0xFE, 0x20])
    assert answer(s, b"\xC9") == bytes([0xFE, 0x20])  # PROGRAM_MAX: no PGM resource
    assert answer(s, b"\xFC") == bytes([0xFE, 0x00])  # SYNCH -> ERR_CMD_SYNCH
    c = s.counters()
    assert (c["err_syntax"], c["err_unknown"], c["ignored"], c["err"]) == (3, 2, 2, 5)


@settings(max_examples=100, deadline=None)
@given(st.lists(cro, min_size=1, max_size=30))
def test_the_slave_is_deterministic(cros):
    """Two instances fed the same CROs and ticks answer byte for byte the same (seeds included)."""
    a, b = unlocked(), unlocked()
    for i, c in enumerate([CONNECT] + cros):
        for s in (a, b):
            s.rx(c, i)
            s.tick(i)
            s.event(0)
        assert a.frames() == b.frames()
    assert a.counters() == b.counters() and memory(a) == memory(b)


@settings(max_examples=150, deadline=None)
@given(st.lists(st.floats(-10, 10, width=32), min_size=16, max_size=16),
       st.lists(st.integers(1, 6), min_size=1, max_size=64), st.lists(st.booleans(), min_size=64, max_size=64))
def test_the_ecu_never_sees_a_matrix_half_written(new, chunks, tick_after):
    """Any chunking of the DOWNLOADs and any ticks in between: the ECU page holds the old matrix
    until the last byte is written and the new one from the next tick on, never a mix."""
    s = unlocked(open_ticks=0)
    g = DESC.item("skf_gain")
    old = s.read("skf_gain")
    blob = struct.pack("<16f", *new)
    new = list(struct.unpack("<16f", blob))
    answer(s, bytes([0xF6, 0, 0, 0]) + struct.pack("<I", g.address))
    pos, tick, k = 0, 0, 0
    while pos < len(blob):
        n = chunks[k % len(chunks)]
        part = blob[pos:pos + n]
        assert answer(s, bytes([0xF0, len(part)]) + part) == b"\xFF"
        pos += len(part)
        if tick_after[k % 64] or pos == len(blob):
            tick += 1
            s.tick(tick)
            assert s.read("skf_gain") == (new if pos == len(blob) else old)
        k += 1


def test_one_element_in_the_middle_of_a_matrix_commits_after_open_ticks():
    s = unlocked(open_ticks=200)
    g = DESC.item("skf_gain")
    answer(s, bytes([0xF6, 0, 0, 0]) + struct.pack("<I", g.address + 5 * 4))
    assert answer(s, bytes([0xF0, 4]) + struct.pack("<f", 7.5)) == b"\xFF"
    for t in range(1, 200):
        s.tick(t)
        assert s.read("skf_gain")[5] == 1.0  # the identity matrix of the reference page
    s.tick(200)  # 200 ticks (100 ms) without a further write: the master is done
    assert s.read("skf_gain")[5] == 7.5 and s.counters()["cal_commits"] == 1


def test_an_element_left_half_written_never_reaches_the_ecu():
    """One byte of a uint16 (20 -> 0x0000 with the high byte still 0): below its minimum of 2. Its
    range check waits for the element's last byte; if that never comes, the write is dropped."""
    s = unlocked(open_ticks=10)
    t = DESC.item("rx_timeout_ticks")
    answer(s, bytes([0xF6, 0, 0, 0]) + struct.pack("<I", t.address))
    assert answer(s, bytes([0xF0, 1, 0x00])) == b"\xFF"
    assert s.read("rx_timeout_ticks", "work") == 0
    for tick in range(1, 12):
        s.tick(tick)
        assert s.read("rx_timeout_ticks") == 20
    assert s.read("rx_timeout_ticks", "work") == 20 and s.counters()["cal_dropped"] == 1
