"""Bus load: frame bit lengths, wire time, per-bus load from our DBC and from foreign ones, the CLI.

Expected stuff-bit counts are not taken from the formulas under test: a small bit-level stuffer below
(5 equal bits -> one complementary bit, which starts the next run) is run on the worst-case bit pattern,
and checked exhaustively on short bit strings.
"""
from __future__ import annotations

import itertools
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
from cantools.database import Database, Message, Signal
from hypothesis import given
from hypothesis import strategies as st

from vehest_can.bus.busload import FD_LENGTHS, bus_load, fd_length, frame_bits, stuff_bits_worst, wire_time_us
from vehest_can.cli import main
from vehest_can.errors import ConfigError
from vehest_can.paths import dbc_path

# --- an independent bit-level reference -----------------------------------------------------------------


def stuffed_after(bits) -> list[int]:
    """Indices of the original bits after which a transmitter inserts a stuff bit."""
    positions, run_value, run = [], None, 0
    for i, b in enumerate(bits):
        if b == run_value:
            run += 1
        else:
            run_value, run = b, 1
        if run == 5:
            positions.append(i)
            run_value, run = 1 - b, 1          # the stuff bit is the complement and starts a new run
    return positions


def worst_pattern(n: int) -> list[int]:
    """0 0 0 0 0, then 4 bits equal to the stuff bit before them, and so on: a stuff bit as often as possible."""
    bits, value = [], 0
    while len(bits) < n:
        bits.extend([value] * (5 if not bits else 4))
        value = 1 - value
    return bits[:n]


@pytest.mark.parametrize("n", range(1, 15))
def test_worst_pattern_is_the_worst_of_all_bit_strings(n):
    most = max(len(stuffed_after(bits)) for bits in itertools.product((0, 1), repeat=n))
    assert most == len(stuffed_after(worst_pattern(n))) == stuff_bits_worst(n)


# --- classic CAN: Davis, Burns, Bril, Lukkien 2007 -------------------------------------------------------


def test_classic_8_bytes_matches_davis_2007():
    assert frame_bits(8) == (135, 0)                      # 11-bit ID, worst case
    assert frame_bits(8, worst_case=False) == (111, 0)
    assert frame_bits(8, extended=True) == (160, 0)       # 29-bit: 64 + 67 + floor(117 / 4)
    assert frame_bits(8, extended=True, worst_case=False) == (131, 0)
    assert frame_bits(0) == (47 + 8, 0)                   # 47 + floor(33 / 4)


def test_issue_figure_2khz_classic_frame_is_54_percent_of_500k():
    # 135 bits at 500 kbit/s = 270 us, once every 500 us.
    assert wire_time_us(frame_bits(8), 500_000) / 500 == pytest.approx(0.54)


@pytest.mark.parametrize("length", range(9))
@pytest.mark.parametrize("extended", [False, True])
def test_classic_stuff_bits_from_the_bit_level_stuffer(length, extended):
    stuffable = (1 + 11 + 1 + 1 + 1 + 4 if not extended else 1 + 11 + 1 + 1 + 18 + 1 + 1 + 1 + 4) + 8 * length + 15
    fixed_tail = 1 + 2 + 7 + 3                            # CRC delimiter, ACK, EOF, intermission
    expected = stuffable + fixed_tail + len(stuffed_after(worst_pattern(stuffable)))
    assert frame_bits(length, extended=extended) == (expected, 0)
    assert frame_bits(length, extended=extended, worst_case=False) == (stuffable + fixed_tail, 0)


# --- CAN FD: ISO 11898-1:2015, worked by hand ------------------------------------------------------------


def fd_fields(length: int, extended: bool):
    """The FD frame field by field as (name, bits, phase); phase 'arb' and 'tail' at the nominal rate."""
    ident = ([("SOF", 1), ("ID", 11), ("RRS", 1), ("IDE", 1)] if not extended else
             [("SOF", 1), ("ID", 11), ("SRR", 1), ("IDE", 1), ("ID ext", 18), ("RRS", 1)])
    arb = [(n, b, "arb") for n, b in ident + [("FDF", 1), ("res", 1), ("BRS", 1)]]
    crc = 17 if length <= 16 else 21
    data = [("ESI", 1, "data"), ("DLC", 4, "data"), ("data", 8 * length, "data"),
            ("stuff count", 4, "data"), ("fixed stuff", 6 if crc == 17 else 7, "data"), ("CRC", crc, "data")]
    tail = [(n, b, "tail") for n, b in
            [("CRC delim", 1), ("ACK slot", 1), ("ACK delim", 1), ("EOF", 7), ("IFS", 3)]]
    return arb + data + tail


def fd_expected(length: int, extended: bool, worst: bool):
    fields = fd_fields(length, extended)
    arb = sum(b for _, b, p in fields if p == "arb")
    tail = sum(b for _, b, p in fields if p == "tail")
    data = sum(b for _, b, p in fields if p == "data")
    if not worst:
        return arb + tail, data
    # Dynamic stuffing runs from SOF to the end of the data field; stuff bits inserted before BRS
    # (after original bit index < arb - 1) are sent at the nominal rate, later ones at the data rate.
    region = arb + 1 + 4 + 8 * length
    after = stuffed_after(worst_pattern(region))
    in_arb = sum(i < arb - 1 for i in after)
    return arb + tail + in_arb, data + len(after) - in_arb


def test_fd_16_bytes_base_id_worked_by_hand():
    # Nominal rate: SOF 1 + ID 11 + RRS 1 + IDE 1 + FDF 1 + res 1 + BRS 1 = 17, tail 1+1+1+7+3 = 13 -> 30.
    # Data rate: ESI 1 + DLC 4 + 128 + stuff count 4 + fixed stuff 6 + CRC17 = 160.
    # Worst case: 17 + 5 + 128 = 150 stuffable bits -> floor(149 / 4) = 37 stuff bits, of which 3 (after
    # bits 5, 9, 13) come before BRS: (30 + 3, 160 + 34) = (33, 194).
    assert fd_expected(16, False, worst=False) == (30, 160)
    assert fd_expected(16, False, worst=True) == (33, 194)
    assert frame_bits(16, fd=True, brs=True, worst_case=False) == (30, 160)
    assert frame_bits(16, fd=True, brs=True) == (33, 194)
    # Our DLS_Sensors frame at 500 kbit/s / 4 Mbit/s: 66 us + 48.5 us.
    assert wire_time_us((33, 194), 500_000, 4_000_000) == pytest.approx(114.5)


def test_fd_64_bytes_extended_id_worked_by_hand():
    # Nominal rate: 36 + 13 = 49; data rate: 1 + 4 + 512 + 4 + 7 + 21 = 549.
    # Worst case: 36 + 5 + 512 = 553 stuffable bits -> 138 stuff bits, 8 of them before BRS.
    assert fd_expected(64, True, worst=False) == (49, 549)
    assert fd_expected(64, True, worst=True) == (57, 679)
    assert frame_bits(64, extended=True, fd=True, brs=True) == (57, 679)


@pytest.mark.parametrize("length", FD_LENGTHS)
@pytest.mark.parametrize("extended", [False, True])
@pytest.mark.parametrize("worst", [False, True])
def test_fd_all_lengths_against_the_field_list(length, extended, worst):
    nominal, data = fd_expected(length, extended, worst)
    assert frame_bits(length, extended=extended, fd=True, brs=True, worst_case=worst) == (nominal, data)
    # Without bit rate switching the same bits are all sent at the nominal rate.
    assert frame_bits(length, extended=extended, fd=True, worst_case=worst) == (nominal + data, 0)


def test_fd_lengths_round_up_and_bad_lengths_are_config_errors():
    assert [fd_length(n) for n in (0, 8, 9, 13, 17, 25, 33, 49, 64)] == [0, 8, 12, 16, 20, 32, 48, 64, 64]
    with pytest.raises(ConfigError):
        fd_length(65)
    with pytest.raises(ConfigError):
        frame_bits(13, fd=True)
    with pytest.raises(ConfigError):
        frame_bits(9)
    with pytest.raises(ConfigError):
        frame_bits(8, brs=True)


# --- properties ------------------------------------------------------------------------------------------

kinds = st.fixed_dictionaries({"extended": st.booleans(), "fd": st.booleans(), "brs": st.booleans()}).filter(
    lambda k: k["fd"] or not k["brs"])


def lengths_for(kind):
    return FD_LENGTHS if kind["fd"] else range(9)


@given(kinds, st.booleans())
def test_more_bytes_never_fewer_bits(kind, worst):
    bits = [frame_bits(n, worst_case=worst, **kind) for n in lengths_for(kind)]
    for shorter, longer in zip(bits, bits[1:]):
        assert sum(longer) > sum(shorter)
        assert longer[0] >= shorter[0] and longer[1] >= shorter[1]


@given(kinds, st.data())
def test_worst_case_never_below_nominal(kind, data):
    n = data.draw(st.sampled_from(lengths_for(kind)))
    worst, nominal = frame_bits(n, **kind), frame_bits(n, worst_case=False, **kind)
    assert worst[0] >= nominal[0] and worst[1] >= nominal[1] and sum(worst) > sum(nominal)


@given(st.sampled_from(FD_LENGTHS), st.booleans(), st.integers(10_000, 1_000_000),
       st.integers(1, 10_000_000), st.integers(1, 10_000_000))
def test_higher_rates_never_take_longer(n, extended, bitrate, d1, d2):
    bits = frame_bits(n, extended=extended, fd=True, brs=True)
    slow, fast = sorted((bitrate + d1, bitrate + d2))
    assert wire_time_us(bits, bitrate, fast) <= wire_time_us(bits, bitrate, slow)
    assert wire_time_us(bits, 2 * bitrate, slow) <= wire_time_us(bits, bitrate, slow)
    # Switching to a data rate at least the nominal one never costs time.
    assert wire_time_us(bits, bitrate, slow) <= wire_time_us((sum(bits), 0), bitrate)


@given(st.lists(st.integers(0, 1), min_size=1, max_size=600))
def test_no_bit_string_needs_more_stuff_bits_than_the_bound(bits):
    assert len(stuffed_after(bits)) <= stuff_bits_worst(len(bits))


# --- our own bus -----------------------------------------------------------------------------------------


def test_project_bus_within_60_percent_at_documented_rates():
    load = bus_load(dbc_path("pt"))
    assert (load.bus, load.bitrate, load.data_bitrate) == ("vehest_pt", 500_000, 4_000_000)
    assert load.worst_pct <= 60.0
    assert load.nominal_pct < load.worst_pct
    by_name = {f.name: f for f in load.frames}
    assert by_name["DLS_Sensors"].cycle_us == 500 and by_name["DLS_Sensors"].cycle_source == "CycleTimeUs"
    assert by_name["DLS_Sensors"].fd and by_name["DLS_Sensors"].brs
    assert by_name["VEHEST_Status"].cycle_us == 10_000      # CycleTimeUs wins over GenMsgCycleTime 10 ms
    assert not any(f.event for f in load.frames)  # the car's bus: the lockstep frames are vehest_sim.dbc's
    sim = {f.name: f for f in bus_load(dbc_path("sim"), 500_000).frames}
    assert {n for n, f in sim.items() if f.event} == {"SIM_Sync", "VEHEST_SyncAck"}
    assert not sim["SIM_Sync"].fd and sim["SIM_Sync"].bits_worst == (135, 0)
    # The total is the sum of the cyclic frames' wire time over their cycle time.
    expected = sum(100 * f.wire_us_worst / f.cycle_us for f in load.frames if not f.event)
    assert load.worst_pct == pytest.approx(expected)


def test_bitrate_arguments_override_the_dbc():
    load = bus_load(dbc_path("pt"), 500_000, 2_000_000)
    assert load.data_bitrate == 2_000_000
    assert load.worst_pct > bus_load(dbc_path("pt")).worst_pct
    with pytest.raises(ConfigError, match="lower than"):
        bus_load(dbc_path("pt"), 500_000, 250_000)
    with pytest.raises(ConfigError):
        bus_load(dbc_path("pt"), -500_000)


# --- foreign DBCs ----------------------------------------------------------------------------------------


@pytest.fixture
def foreign_dbc(tmp_path) -> Path:
    """A classic-CAN DBC as other tools write it: GenMsgCycleTime only, extended IDs, no bit rate."""
    db = Database(messages=[
        Message(frame_id=0x18FEF100, name="CCVS", length=8, is_extended_frame=True, cycle_time=10,
                signals=[Signal("WheelSpeed", start=8, length=16)]),
        Message(frame_id=0x123, name="Lights", length=4, cycle_time=20,
                signals=[Signal("Lamp", start=0, length=8)]),
        Message(frame_id=0x18EA00FE, name="Request", length=3, is_extended_frame=True,
                signals=[Signal("Pgn", start=0, length=24)]),
    ])
    path = tmp_path / "truck_body.dbc"
    path.write_text(db.as_dbc_string(), encoding="cp1252")
    assert "Baudrate" not in path.read_text(encoding="cp1252")
    return path


def davis(n: int, extended: bool) -> int:
    return 8 * n + (67 if extended else 47) + (8 * n + (54 if extended else 34) - 1) // 4


def test_foreign_dbc_needs_a_bitrate(foreign_dbc):
    with pytest.raises(ConfigError, match="truck_body.dbc.*--bitrate"):
        bus_load(foreign_dbc)


def test_foreign_dbc_load(foreign_dbc):
    load = bus_load(foreign_dbc, 250_000)
    assert load.bus == "truck_body" and load.data_bitrate is None
    by_name = {f.name: f for f in load.frames}
    assert by_name["CCVS"].extended and by_name["CCVS"].cycle_source == "GenMsgCycleTime"
    assert by_name["Request"].event and (load.cyclic_frames, load.event_frames) == (2, 1)
    ccvs_us = davis(8, True) / 250_000 * 1e6          # 160 bits = 640 us every 10 ms
    lights_us = davis(4, False) / 250_000 * 1e6       # 95 bits = 380 us every 20 ms
    assert load.worst_pct == pytest.approx(100 * (ccvs_us / 10_000 + lights_us / 20_000))
    assert load.worst_pct == pytest.approx(8.3)
    nominal = 100 * ((64 + 67) / 250_000 / 0.010 + (32 + 47) / 250_000 / 0.020)
    assert load.nominal_pct == pytest.approx(nominal)


DBC_2KHZ_CLASSIC = """VERSION ""

NS_ :

BS_:

BU_: ECU

BO_ 291 Fast: 8 ECU
 SG_ A : 0|16@1+ (1,0) [0|65535] "" Vector__XXX

BO_ 292 Odd: 13 ECU
 SG_ B : 0|8@1+ (1,0) [0|255] "" Vector__XXX

BA_DEF_ BO_ "CycleTimeUs" INT 0 100000000;
BA_DEF_ BO_ "GenMsgCycleTime" FLOAT 0 65535;
BA_DEF_DEF_ "CycleTimeUs" 0;
BA_DEF_DEF_ "GenMsgCycleTime" 0;
BA_ "CycleTimeUs" BO_ 291 500;
BA_ "GenMsgCycleTime" BO_ 291 0.5;
BA_ "GenMsgCycleTime" BO_ 292 100;
"""


def test_cycle_time_us_and_odd_lengths(tmp_path):
    path = tmp_path / "fast.dbc"
    path.write_text(DBC_2KHZ_CLASSIC)
    load = bus_load(path, 500_000)
    fast, odd = load.frames
    assert fast.cycle_us == 500 and fast.worst_pct == pytest.approx(54.0)   # the issue's figure
    assert fast.nominal_pct == pytest.approx(100 * 111 / 500_000 / 500e-6)
    # 13 bytes without VFrameFormat: must be FD, and 13 is no FD length -> 16; no data rate -> no BRS.
    assert (odd.fd, odd.brs, odd.wire_length) == (True, False, 16)
    assert any("16" in n for n in odd.notes) and any("bit rate switching" in n for n in odd.notes)
    assert odd.bits_worst == (sum(fd_expected(16, False, True)), 0)


def test_cycle_attributes_that_disagree_are_an_error(tmp_path):
    """GenMsgCycleTime 1 ms (what cantools and canmatrix show) beside CycleTimeUs 500 (what the firmware
    runs): refused by the bus load and by the firmware build alike."""
    path = tmp_path / "fast.dbc"
    path.write_text(DBC_2KHZ_CLASSIC.replace('BO_ 291 0.5;', 'BO_ 291 1;'))
    why = r"Fast \(0x123\): GenMsgCycleTime = 1 ms and CycleTimeUs = 500 us disagree"
    with pytest.raises(ConfigError, match=why):
        bus_load(path, 500_000)
    code = ("import sys; sys.path.insert(0, 'c_core'); import dbcgen, cantools; "
            f"dbcgen.meta_header(cantools.database.load_file({str(path)!r}), 'vh_x')")
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 1 and re.search(rf"DbcError: {why}", r.stderr), r.stderr


# --- cyclic frames without a cycle time ---------------------------------------------------------------

ROOT = Path(__file__).resolve().parents[2]


def zero_cycle_pt(tmp_path) -> Path:
    """The project's powertrain DBC with the 2 kHz DLS_Sensors given cycle time 0."""
    text = dbc_path("pt").read_text()
    for line in ('BA_ "CycleTimeUs" BO_ 256 500;', 'BA_ "GenMsgCycleTime" BO_ 256 0.5;'):
        assert line in text
        text = text.replace(line, line.rsplit(" ", 1)[0] + " 0;")
    path = tmp_path / "zero.dbc"
    path.write_text(text)
    return path


ZERO_CYCLE = r"DLS_Sensors \(0x100\) is cyclic \(GenMsgSendType = Cyclic; CycleTimeUs = 0; GenMsgCycleTime = 0.0; " \
             r"RxTimeoutCycles = 4: " \
             r"received with a timeout\) but has no cycle time"


def test_a_2khz_frame_with_cycle_time_0_is_an_error_not_an_event_frame(tmp_path, capsys):
    path = zero_cycle_pt(tmp_path)
    with pytest.raises(ConfigError, match=rf"zero\.dbc: {ZERO_CYCLE}"):
        bus_load(path)
    assert main(["busload", str(path)]) == 1
    err = capsys.readouterr().err
    assert re.match(rf"error: .*zero\.dbc: {ZERO_CYCLE}: give it a CycleTimeUs", err) and "Traceback" not in err
    assert err.count("\n") == 1


ONE_FRAME = """VERSION ""

NS_ :

BS_:

BU_: ECU

BO_ 291 Fast: 8 ECU
 SG_ A : 0|16@1+ (1,0) [0|65535] "" Vector__XXX

BA_DEF_ BO_ "CycleTimeUs" INT 0 100000000;
BA_DEF_ BO_ "GenMsgCycleTime" INT 0 65535;
BA_DEF_ BO_ "GenMsgSendType" ENUM "Cyclic","Event";
BA_DEF_ BO_ "RxTimeoutCycles" INT 0 255;
BA_DEF_DEF_ "CycleTimeUs" 0;
BA_DEF_DEF_ "GenMsgCycleTime" 0;
BA_DEF_DEF_ "GenMsgSendType" "Event";
BA_DEF_DEF_ "RxTimeoutCycles" 0;
"""


def one_frame_dbc(tmp_path, attributes: str) -> Path:
    path = tmp_path / "one.dbc"
    path.write_text(ONE_FRAME + attributes)
    return path


@pytest.mark.parametrize("attributes, why", [
    ('BA_ "GenMsgSendType" BO_ 291 0;\n', "GenMsgSendType = Cyclic"),
    ('BA_ "GenMsgCycleTime" BO_ 291 0;\n', "GenMsgCycleTime = 0"),
    ('BA_ "CycleTimeUs" BO_ 291 0;\n', "CycleTimeUs = 0"),
    ('BA_ "RxTimeoutCycles" BO_ 291 3;\n', "RxTimeoutCycles = 3: received with a timeout"),
])
def test_each_way_a_dbc_marks_a_frame_cyclic(tmp_path, attributes, why):
    path = one_frame_dbc(tmp_path, attributes)
    with pytest.raises(ConfigError, match=rf"Fast \(0x123\) is cyclic \({re.escape(why)}\) but has no cycle time"):
        bus_load(path, 500_000)
    # the same frame with its cycle time: 54 % of the bus, as a 2 kHz 8-byte frame is
    ok = one_frame_dbc(tmp_path, attributes + 'BA_ "CycleTimeUs" BO_ 291 500;\n')  # the last BA_ counts
    assert bus_load(ok, 500_000).worst_pct == pytest.approx(54.0)


@pytest.mark.parametrize("attributes", [
    "",                                                                  # nothing says cyclic
    'BA_ "GenMsgSendType" BO_ 291 1;\nBA_ "GenMsgCycleTime" BO_ 291 0;\n',  # Event, as tools write it
])
def test_event_frames_stay_event_frames(tmp_path, attributes):
    (frame,) = bus_load(one_frame_dbc(tmp_path, attributes), 500_000).frames
    assert frame.event and frame.worst_pct == 0


def test_the_firmware_build_refuses_the_same_frames(tmp_path):
    """c_core/dbcgen.py applies the same rule, loading vehest_can/bus/cyclic.py alone (no package import)."""
    code = ("import sys; sys.path.insert(0, 'c_core'); import dbcgen, cantools; "
            "assert not [m for m in sys.modules if m.startswith('vehest_can')], 'dbcgen imported vehest_can'; "
            f"dbcgen.meta_header(cantools.database.load_file({str(dbc_path('pt'))!r}), 'vh_pt'); "
            f"dbcgen.meta_header(cantools.database.load_file({str(zero_cycle_pt(tmp_path))!r}), 'vh_pt')")
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 1 and "dbcgen imported" not in r.stderr, r.stderr
    assert re.search(rf"ValueError: vh_pt: {ZERO_CYCLE}", r.stderr), r.stderr


# --- CLI -------------------------------------------------------------------------------------------------


def test_cli_project_bus(capsys):
    assert main(["busload", str(dbc_path("pt")), "--frames"]) == 0
    out = capsys.readouterr().out
    load = bus_load(dbc_path("pt"))
    assert "vehest_pt" in out and "500k/4M" in out and f"{load.worst_pct:.1f}" in out
    assert "DLS_Sensors" in out and "33+239" in out and "event" in out  # 20 bytes: 16 + the SecOC tail


def test_cli_foreign_bus_json_and_limit(foreign_dbc, capsys):
    assert main(["busload", str(foreign_dbc), "-b", "250k", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    (bus,) = doc["buses"]
    assert bus["bus"] == "truck_body" and bus["within_limit"] and bus["worst_pct"] == pytest.approx(8.3)
    assert bus["event_frames"] == 1 and len(bus["frames"]) == 3

    assert main(["busload", str(foreign_dbc), "-b", "250000", "--limit", "5"]) == 2
    captured = capsys.readouterr()
    assert "EXCEEDED" in captured.out and "truck_body" in captured.err and "exceeds" in captured.err


def test_cli_several_buses_one_over_limit(foreign_dbc, capsys):
    assert main(["busload", str(dbc_path("pt")), str(foreign_dbc), "-b", "125k", "--data-bitrate", "2M"]) == 2
    captured = capsys.readouterr()
    assert "vehest_pt" in captured.err and "truck_body" not in captured.err


@pytest.mark.parametrize("args, message", [
    (["missing.dbc", "-b", "500k"], "missing.dbc"),
    (["{garbage}", "-b", "500k"], "not a readable DBC"),
    (["{pt}", "--bitrate=-500000"], "--bitrate"),
    (["{pt}", "--bitrate", "fast"], "--bitrate"),
    (["{pt}", "--bitrate", "0"], "--bitrate"),
    (["{pt}", "-b", "500k", "--data-bitrate", "250k"], "lower than"),
    (["{pt}", "--limit", "0"], "--limit"),
    (["{foreign}"], "--bitrate"),
    (["{big}", "-b", "500k"], "at most 64"),
])
def test_cli_errors(args, message, tmp_path, foreign_dbc, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    garbage = tmp_path / "garbage.dbc"
    garbage.write_bytes(bytes(range(256)) * 4)
    big = tmp_path / "big.dbc"
    big.write_text('VERSION ""\n\nBO_ 1 Huge: 80 ECU\n SG_ A : 0|8@1+ (1,0) [0|255] "" Vector__XXX\n')
    names = {"garbage": str(garbage), "pt": str(dbc_path("pt")), "foreign": str(foreign_dbc), "big": str(big)}
    assert main(["busload", *(a.format(**names) for a in args)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: ") and message in err and "Traceback" not in err
