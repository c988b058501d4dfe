"""Fault counters saturate, never wrap: uint32 in the ECU (vh_sat_add_u32), each 16-bit field of a
status frame stopped at 65535 with the frame's CntSaturated bit set (vh_sat_field_u32).

Driven through cffi on the real C (the RX path, the packers), read back from the frames the ECU
sends, decoded with cantools from the DBC."""
import re
from pathlib import Path

import can
from hypothesis import example, given
from hypothesis import strategies as st

from vehest_can.bus.frames import frame_id, message
from vehest_can.native import ffi, lib
from vehest_can.systems.ecu import Ecu

ROOT = Path(__file__).resolve().parent.parent
U32_MAX = 2**32 - 1


@given(st.integers(0, U32_MAX), st.integers(0, U32_MAX))
@example(U32_MAX, 1)
@example(U32_MAX - 2, 7)
def test_sat_add_u32_is_the_sum_stopped_at_its_maximum(a, b):
    assert lib.vh_sat_add_u32(a, b) == min(a + b, U32_MAX)


@given(st.integers(0, U32_MAX), st.sampled_from([0xFFF, 0xFFFF]))
@example(0xFFFF, 0xFFFF)
@example(0xFFFE, 0xFFFF)
def test_a_field_holds_the_count_or_its_maximum_and_says_so(count, top):
    sat = ffi.new("uint8_t *")
    assert lib.vh_sat_field_u32(count, top, sat) == min(count, top)
    assert sat[0] == (count >= top)


def status_frames(ecu: Ecu, name: str, ticks: int) -> list[dict]:
    """`name` frames the ECU sends in `ticks` ticks, decoded through the DBC."""
    msg = message(name)
    return [msg.decode(m.data, decode_choices=False) for _ in range(ticks) for m in ecu.step()
            if m.arbitration_id == msg.frame_id]


def bad_crc_frame() -> can.Message:
    bad = bytearray(message("DLS_Sensors").length)
    bad[0] = 0x55
    return can.Message(arbitration_id=frame_id("DLS_Sensors"), is_extended_id=False, is_fd=True, data=bytes(bad))


def test_vehest_status_field_stays_at_65535_with_the_flag_set_past_it():
    ecu = Ecu()
    bad = bad_crc_frame()
    for _ in range(65_534):  # through the real RX path: length, E2E, counted
        ecu.rx(bad)
    (st0,) = status_frames(ecu, "VEHEST_Status", 20)[-1:]
    assert (st0["CntCrcError"], st0["CntSaturated"]) == (65_534, 0)  # below the maximum: exact, no flag
    for _ in range(70_000 - 65_534):
        ecu.rx(bad)
    st1 = status_frames(ecu, "VEHEST_Status", 20)[-1]
    assert int(ecu.c.cnt.crc_error) == 70_000 == ecu.counters()["crc_error"]  # all 32 bits
    assert (st1["CntCrcError"], st1["CntSaturated"]) == (65_535, 1)
    assert st1["CntCounterSkip"] == 0  # the other fields stay exact


def test_the_flag_is_set_at_the_maximum_itself():
    ecu = Ecu()
    ecu.note_deadline_miss(65_535)
    st1 = status_frames(ecu, "VEHEST_Status", 20)[-1]
    assert (st1["CntDeadlineMiss"], st1["CntSaturated"]) == (65_535, 1)  # 65535 reads "65535 or more"


def test_32_bit_counters_stop_at_their_maximum():
    ecu = Ecu()
    ecu.note_deadline_miss(U32_MAX - 1)
    ecu.note_deadline_miss(5)
    assert ecu.counters()["deadline_miss"] == U32_MAX
    ecu.c.cnt.crc_error = U32_MAX
    ecu.rx(bad_crc_frame())
    assert ecu.counters()["crc_error"] == U32_MAX  # not 0
    st1 = status_frames(ecu, "VEHEST_Status", 20)[-1]
    assert (st1["CntCrcError"], st1["CntDeadlineMiss"], st1["CntSaturated"]) == (65_535, 65_535, 1)


def test_chassis_status_saturates_its_fields_and_its_sum():
    ecu = Ecu()
    tf = ecu.c.app.tf
    tf.heard = 1  # the status is sent once CHS_Sensors was heard; the counters below are what is tested
    assert status_frames(ecu, "VEHEST_ChassisStatus", 20)[-1]["CntSaturated"] == 0
    tf.cnt.counter_repeat, tf.cnt.counter_skip = U32_MAX - 2, 7  # a wrapping sum would read 4
    tf.cnt.crc_error = 0x1_0005  # a wrapping 16-bit field would read 5
    st1 = status_frames(ecu, "VEHEST_ChassisStatus", 20)[-1]
    assert (st1["CntRxCounterError"], st1["CntRxCrcError"], st1["CntSaturated"]) == (65_535, 65_535, 1)
    assert st1["CntRxTimeout"] < 65_535
    assert ecu.chassis_counters()["crc_error"] == 0x1_0005


def test_no_counter_increments_outside_the_saturating_helpers():
    """Every fault counter of the firmware counts through vh_rx_count / vh_sat_add_u32: no `++`,
    `+=` or 16-bit cast on a counter field anywhere in c_core."""
    pattern = re.compile(r"\b(cnt|n_contra)\b[\w.>\[\]-]*\s*(\+\+|\+=)|\+\+\s*[\w.>-]*\b(cnt|n_contra)\b"
                         r"|\(uint16_t\)\([^;]*\bcnt\b[^;]*\+")
    hits = [f"{p.relative_to(ROOT)}:{i}: {line.strip()}" for p in sorted((ROOT / "c_core").rglob("*.c"))
            for i, line in enumerate(p.read_text().splitlines(), 1) if pattern.search(line)]
    assert hits == []
