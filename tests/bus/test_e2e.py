"""AUTOSAR E2E in C (vh_e2e.c): its CRCs against textbook bitwise CRCs written here from the CRC
library's parameters, and every profile and data ID mode against an independent implementation of
the AUTOSAR E2E library (the ``autosar-e2e`` package), in both directions."""
import e2e.p01
import e2e.p02
import e2e.p05
import pytest
from hypothesis import given
from hypothesis import strategies as st

from vehest_can.native import ffi, lib


def crc8(data: bytes, poly: int, crc: int) -> int:
    """Textbook MSB-first CRC-8 without final XOR."""
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ poly) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


def crc16_ccitt(data: bytes, crc: int = 0xFFFF) -> int:
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def test_crc_check_values():
    # AUTOSAR CRC library check values over "123456789"
    assert lib.vh_crc8_j1850_update(0xFF, b"123456789", 9) ^ 0xFF == 0x4B
    assert lib.vh_crc8h2f_update(0xFF, b"123456789", 9) ^ 0xFF == 0xDF
    assert lib.vh_crc16_ccitt_update(0xFFFF, b"123456789", 9) == 0x29B1
    # and the J1850 library's other check values
    for data, value in ((b"\x00\x00\x00\x00", 0x59), (b"\xF2\x01\x83", 0x37), (b"\xFF\xFF\xFF\xFF", 0x74)):
        assert lib.vh_crc8_j1850_update(0xFF, data, len(data)) ^ 0xFF == value


@given(st.binary(min_size=0, max_size=64), st.integers(0, 255), st.integers(0, 0xFFFF))
def test_crc_tables_match_bitwise(data, start8, start16):
    assert lib.vh_crc8_j1850_update(start8, data, len(data)) == crc8(data, 0x1D, start8)
    assert lib.vh_crc8h2f_update(start8, data, len(data)) == crc8(data, 0x2F, start8)
    assert lib.vh_crc16_ccitt_update(start16, data, len(data)) == crc16_ccitt(data, start16)


MODES = {"BOTH": (lib.VH_E2E_ID_BOTH, e2e.p01.E2E_P01_DATAID_BOTH, 0xFFFF),
         "ALT": (lib.VH_E2E_ID_ALT, e2e.p01.E2E_P01_DATAID_ALT, 0xFFFF),
         "LOW": (lib.VH_E2E_ID_LOW, e2e.p01.E2E_P01_DATAID_LOW, 0xFF),
         "NIBBLE": (lib.VH_E2E_ID_NIBBLE, e2e.p01.E2E_P01_DATAID_NIBBLE, 0xFFF)}


def cfg(profile: int, data_id: int = 0, mode: int = 0, id_list: bytes = bytes(16)):
    return ffi.new("vh_e2e_cfg_t *", {"profile": profile, "id_mode": mode, "data_id": data_id,
                                       "id_list": list(id_list)})


def protect(c, payload: bytes, counter) -> bytearray:
    buf = ffi.new("uint8_t[]", payload)
    lib.vh_e2e_protect(c, buf, len(payload), counter)
    return bytearray(ffi.buffer(buf, len(payload)))


def check(c, rx, frame) -> int:
    return lib.vh_e2e_check(c, rx, bytes(frame), len(frame))


def fresh_rx():
    rx = ffi.new("vh_e2e_rx_t *")
    lib.vh_e2e_rx_init(rx)
    return rx


@pytest.mark.parametrize("mode", MODES)
@given(payload=st.binary(min_size=3, max_size=32), data_id=st.integers(0, 0xFFFF), counter=st.integers(0, 14))
def test_p01_as_autosar_e2e_computes_it(mode, payload, data_id, counter):
    ours, theirs, id_max = MODES[mode]
    data_id &= id_max
    c = cfg(lib.VH_E2E_P01, data_id, ours)
    frame = protect(c, payload, ffi.new("uint8_t *", counter))
    assert frame[1] & 0x0F == counter
    assert e2e.p01.e2e_p01_check(bytearray(frame), data_id, data_id_mode=theirs)
    # and the library's frame (it advances the counter it finds, then protects) passes ours
    mine = bytearray(payload)
    mine[1] = (mine[1] & 0xF0) | ((counter + 14) % 15)
    e2e.p01.e2e_p01_protect(mine, data_id, data_id_mode=theirs)
    assert mine == frame
    assert check(c, fresh_rx(), mine) == lib.VH_E2E_INITIAL


@given(payload=st.binary(min_size=3, max_size=64), id_list=st.binary(min_size=16, max_size=16),
       counter=st.integers(0, 15))
def test_p02_as_autosar_e2e_computes_it(payload, id_list, counter):
    c = cfg(lib.VH_E2E_P02, id_list=id_list)
    frame = protect(c, payload, ffi.new("uint8_t *", counter))
    assert frame[1] & 0x0F == counter
    assert e2e.p02.e2e_p02_check(bytearray(frame), id_list)
    mine = bytearray(payload)
    mine[1] = (mine[1] & 0xF0) | ((counter + 15) % 16)
    e2e.p02.e2e_p02_protect(mine, id_list)
    assert mine == frame


@given(payload=st.binary(min_size=4, max_size=64), data_id=st.integers(0, 0xFFFF), counter=st.integers(0, 255))
def test_p05_as_autosar_e2e_computes_it(payload, data_id, counter):
    c = cfg(lib.VH_E2E_P05, data_id)
    frame = protect(c, payload, ffi.new("uint8_t *", counter))
    assert frame[2] == counter
    assert e2e.p05.e2e_p05_check(bytearray(frame), data_id)
    mine = bytearray(payload)
    mine[2] = (counter + 255) % 256
    e2e.p05.e2e_p05_protect(mine, data_id)
    assert mine == frame
    assert check(c, fresh_rx(), mine) == lib.VH_E2E_INITIAL


PROFILES = {"P01": (lib.VH_E2E_P01, 15), "P02": (lib.VH_E2E_P02, 16), "P05": (lib.VH_E2E_P05, 256)}


@pytest.mark.parametrize("name", PROFILES)
def test_counter_sequence_and_check_states(name):
    profile, period = PROFILES[name]
    c = cfg(profile, 0x1100, id_list=bytes(range(16)))
    counter = ffi.new("uint8_t *", 0)
    rx = fresh_rx()
    frames = [protect(c, bytes(8), counter) for _ in range(period + 2)]
    assert [lib.vh_e2e_counter(c, bytes(f)) for f in frames] == [k % period for k in range(period + 2)]
    states = [check(c, rx, f) for f in frames]
    assert states[0] == lib.VH_E2E_INITIAL and set(states[1:]) == {lib.VH_E2E_OK}
    assert check(c, rx, frames[-1]) == lib.VH_E2E_REPEATED
    protect(c, bytes(8), counter)  # one frame lost on the way
    assert check(c, rx, protect(c, bytes(8), counter)) == lib.VH_E2E_SKIPPED
    bad = protect(c, bytes(8), counter)
    bad[5] ^= 0x10
    assert check(c, rx, bad) == lib.VH_E2E_WRONG_CRC
    good = protect(c, bytes(8), counter)
    assert check(cfg(profile, 0x1101, id_list=bytes(range(1, 17))), rx, good) == lib.VH_E2E_WRONG_CRC
    assert lib.vh_e2e_check(c, rx, bytes(good), 2) == lib.VH_E2E_BAD_LEN


def test_p01_counter_15_and_a_foreign_nibble_are_refused():
    c = cfg(lib.VH_E2E_P01, 0x0123, lib.VH_E2E_ID_NIBBLE)
    frame = protect(c, bytes(8), ffi.new("uint8_t *", 4))
    assert frame[1] >> 4 == 0x1  # data ID bits 8..11, sent
    assert check(cfg(lib.VH_E2E_P01, 0x0523, lib.VH_E2E_ID_NIBBLE), fresh_rx(), frame) == lib.VH_E2E_WRONG_CRC
    both = cfg(lib.VH_E2E_P01, 0x1100)
    frame = bytearray(8)
    frame[1] = 0x0F  # counter 15 is never sent, whatever the CRC
    frame[0] = crc8(bytes([0x00, 0x11]) + bytes(frame[1:]), 0x1D, 0x00)
    assert check(both, fresh_rx(), frame) == lib.VH_E2E_WRONG_CRC


def test_an_unprotected_frame_passes_untouched():
    c = cfg(lib.VH_E2E_NONE)
    counter = ffi.new("uint8_t *", 7)
    assert protect(c, bytes(range(8)), counter) == bytes(range(8)) and counter[0] == 7
    assert check(c, fresh_rx(), bytes(8)) == lib.VH_E2E_OK


@pytest.mark.parametrize("name", PROFILES)
@pytest.mark.parametrize("flip_bit", range(0, 8 * 16, 3))
def test_single_bit_errors_are_detected(name, flip_bit):
    c = cfg(PROFILES[name][0], 0x1100, id_list=bytes(range(16)))
    frame = protect(c, bytes(range(16)), ffi.new("uint8_t *", 3))
    frame[flip_bit // 8] ^= 1 << (flip_bit % 8)
    assert check(c, fresh_rx(), frame) == lib.VH_E2E_WRONG_CRC
