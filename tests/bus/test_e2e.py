"""E2E P01 protection in C against an independent bitwise CRC written here from the spec."""
import pytest
from hypothesis import given
from hypothesis import strategies as st

from vehest_can.native import ffi, lib


def crc8_sae_j1850(data: bytes, crc: int = 0xFF) -> int:
    """Textbook MSB-first CRC-8, poly 0x1D, init 0xFF, xorout 0xFF (AUTOSAR SWS_CRCLibrary)."""
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc ^ 0xFF


def test_crc8_check_values():
    # AUTOSAR CRC library check values for CRC-8 SAE J1850
    assert lib.vh_crc8_j1850(b"123456789", 9) == 0x4B
    assert lib.vh_crc8_j1850(b"\x00\x00\x00\x00", 4) == 0x59
    assert lib.vh_crc8_j1850(b"\xF2\x01\x83", 3) == 0x37
    assert lib.vh_crc8_j1850(b"\xFF\xFF\xFF\xFF", 4) == 0x74


@given(st.binary(min_size=0, max_size=64))
def test_crc8_matches_reference(data):
    assert lib.vh_crc8_j1850(data, len(data)) == crc8_sae_j1850(data)


@given(st.binary(min_size=2, max_size=64), st.integers(0, 0xFFFF))
def test_p01_crc_covers_data_id_then_payload(payload, data_id):
    expected = crc8_sae_j1850(bytes([data_id & 0xFF, data_id >> 8]) + payload[1:])
    assert lib.vh_e2e_p01_crc(payload, len(payload), data_id) == expected


def protect(payload: bytearray, data_id: int, counter):
    buf = ffi.new("uint8_t[]", bytes(payload))
    lib.vh_e2e_p01_protect(buf, len(payload), data_id, counter)
    return bytes(ffi.buffer(buf, len(payload)))


def test_counter_sequence_and_check_states():
    counter = ffi.new("uint8_t *", 0)
    rx = ffi.new("vh_e2e_rx_t *")
    lib.vh_e2e_rx_init(rx)
    frames = [protect(bytearray(8), 0x1100, counter) for _ in range(32)]
    assert [f[1] & 0x0F for f in frames[:16]] == list(range(15)) + [0]  # 0..14 then wraps
    states = [lib.vh_e2e_p01_check(rx, f, 8, 0x1100) for f in frames]
    assert states[0] == lib.VH_E2E_INITIAL
    assert set(states[1:]) == {lib.VH_E2E_OK}
    # repeated, skipped, corrupted, wrong data ID, too short
    assert lib.vh_e2e_p01_check(rx, frames[-1], 8, 0x1100) == lib.VH_E2E_REPEATED
    f = protect(bytearray(8), 0x1100, counter)
    f = protect(bytearray(8), 0x1100, counter)  # one frame lost in between
    assert lib.vh_e2e_p01_check(rx, f, 8, 0x1100) == lib.VH_E2E_SKIPPED
    bad = bytearray(protect(bytearray(8), 0x1100, counter))
    bad[5] ^= 0x10
    assert lib.vh_e2e_p01_check(rx, bytes(bad), 8, 0x1100) == lib.VH_E2E_WRONG_CRC
    good = protect(bytearray(8), 0x1100, counter)
    assert lib.vh_e2e_p01_check(rx, good, 8, 0x1101) == lib.VH_E2E_WRONG_CRC
    assert lib.vh_e2e_p01_check(rx, good, 1, 0x1100) == lib.VH_E2E_BAD_LEN


@pytest.mark.parametrize("flip_bit", range(8 * 16))
def test_every_single_bit_error_is_detected(flip_bit):
    counter = ffi.new("uint8_t *", 3)
    frame = bytearray(protect(bytearray(range(16)), 0x1100, counter))
    frame[flip_bit // 8] ^= 1 << (flip_bit % 8)
    rx = ffi.new("vh_e2e_rx_t *")
    lib.vh_e2e_rx_init(rx)
    assert lib.vh_e2e_p01_check(rx, bytes(frame), 16, 0x1100) == lib.VH_E2E_WRONG_CRC
