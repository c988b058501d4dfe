"""The C codec generated from the DBC equals cantools, byte for byte, for every message."""
import re
import sys
from pathlib import Path

import cantools
import cffi
import pytest
from cantools.database.can.c_source import camel_to_snake_case
from hypothesis import given, settings
from hypothesis import strategies as st

from vehest_can.bus.frames import database
from vehest_can.native import ffi, lib

ROOT = Path(__file__).resolve().parents[2]
DB = database("pt")
MESSAGES = DB.messages


def c_names(message):
    base = f"vh_pt_{camel_to_snake_case(message.name)}"
    return base, f"struct {base}_t"


def raw_strategy(signal):
    lo, hi = (-(1 << (signal.length - 1)), (1 << (signal.length - 1)) - 1) if signal.is_signed else (0, (1 << signal.length) - 1)
    return st.integers(lo, hi)


def message_values(message):
    return st.fixed_dictionaries({s.name: raw_strategy(s) for s in message.signals})


@pytest.mark.parametrize("message", MESSAGES, ids=lambda m: m.name)
@settings(max_examples=200, deadline=None)
@given(data=st.data())
def test_c_pack_equals_cantools_encode(message, data):
    values = data.draw(message_values(message))
    base, struct = c_names(message)
    src = ffi.new(f"{struct} *")
    for sig in message.signals:
        setattr(src, camel_to_snake_case(sig.name), values[sig.name])
    dst = ffi.new("uint8_t[]", message.length)
    assert getattr(lib, f"{base}_pack")(dst, src, message.length) == message.length
    expected = message.encode(values, scaling=False, strict=False, padding=False)
    assert bytes(ffi.buffer(dst, message.length)) == expected


@pytest.mark.parametrize("message", MESSAGES, ids=lambda m: m.name)
@settings(max_examples=200, deadline=None)
@given(data=st.data())
def test_c_unpack_equals_cantools_decode(message, data):
    payload = data.draw(st.binary(min_size=message.length, max_size=message.length))
    base, struct = c_names(message)
    out = ffi.new(f"{struct} *")
    assert getattr(lib, f"{base}_unpack")(out, payload, len(payload)) == 0
    expected = message.decode(payload, decode_choices=False, scaling=False)
    assert {s.name: getattr(out, camel_to_snake_case(s.name)) for s in message.signals} == expected


def test_dbc_loads_strict_without_warnings():
    with _no_warnings():
        db = cantools.database.load_file(str(ROOT / "dbc" / "vehest_pt.dbc"), strict=True)
    assert {m.name for m in db.messages} >= {"DLS_Sensors", "VEHEST_DrivelineEst", "VEHEST_Status"}
    for m in db.messages:
        assert m.senders, f"{m.name} has no sender node"
        assert m.comment, f"{m.name} has no comment"


class _no_warnings:
    def __enter__(self):
        import warnings
        self._cm = warnings.catch_warnings()
        self._cm.__enter__()
        warnings.simplefilter("error")

    def __exit__(self, *exc):
        return self._cm.__exit__(*exc)


def test_generated_code_is_current(tmp_path):
    """The codec is generated from the DBC at build time (in the build's temporary directory): the
    compiled module's codec structs and functions are those of a fresh generation."""
    sys.path.insert(0, str(ROOT / "c_core"))
    import dbcgen

    dbcgen.generate_all(tmp_path)
    fresh = cffi.FFI()
    text = "".join(f.read_text() for f in sorted(tmp_path.glob("*.cdef")))
    fresh.cdef(text)
    structs = fresh.list_types()[1]
    assert len(structs) >= 20
    for name in structs:
        fields = [(n, f.type.cname) for n, f in fresh.typeof(f"struct {name}").fields]
        assert fields == [(n, f.type.cname) for n, f in ffi.typeof(f"struct {name}").fields], f"{name} is stale: reinstall"
    for fn in re.findall(r"\b(vh_\w+)\(", text):
        assert hasattr(lib, fn), f"{fn} is missing: reinstall"


def test_firmware_sources_do_not_hand_parse_or_include_the_simulator():
    for src in (p for d in ("common", "ecu", "driveline", "tireforce", "camber") for p in (ROOT / "c_core" / d).glob("*.c")):
        text = src.read_text()
        assert not re.search(r'#include\s+"(vh_dlplant|vh_dlsnode|vh_rng|vh_cambernode|vh_dlsim)\.h"', text), src
    ecu = "".join(p.read_text() for p in sorted((ROOT / "c_core").glob("*/vh_*_app.c")))  # the ECU's RX/TX
    assert "vh_pt_dls_sensors_unpack" in ecu and "vh_pt_vehest_driveline_est_pack" in ecu
    assert not re.search(r"data\[\d+\]\s*(<<|>>|&)", ecu), "vh_ecu.c must not hand-parse frame bytes"
