"""The tyre-force ECU application's integer path (issue 10, item 5, as far as it goes).

CHS_Sensors raw signals reach the fixed-point SKFMEC by an exact integer scaling (the DBC scale as
a fraction, generated vh_ch_q.h): checked here against the double path it replaced (decode in
double, then round to the Q format) for every raw value of every signal, so the ECU's inputs are
the same integers as before. The tyre forces Fy1..Fy4 go out the same way (Q.FN -> raw, exact).
"""
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import cantools
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vehest_can.native import ffi, lib

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "c_core"))
import dbcgen  # noqa: E402
import vehest_build  # noqa: E402

I32_MIN, I32_MAX = -(2**31), 2**31 - 1
CH = cantools.database.load_file(str(ROOT / "dbc" / "vehest_ch.dbc"))
CHS = CH.get_message_by_name("CHS_Sensors")
TFE = CH.get_message_by_name("VEHEST_TireForceEst")
FRAC = {"LongAccel": "FA", "LatAccel": "FA", "YawRate": "FW", "RollRate": "FW", "SteerAngle": "FD",
        **{f"WheelSpeed{w}": "FO" for w in ("FL", "FR", "RL", "RR")},
        **{f"WheelTorque{w}": "FT" for w in ("FL", "FR", "RL", "RR")}}


def fn(msg, sig, kind):
    return getattr(lib, f"vh_ch_{dbcgen.camel_to_snake_case(msg.name)}_{dbcgen.camel_to_snake_case(sig.name)}_{kind}")


def double_path(raw, scale, frac):
    """What the ECU did before: cantools' decode (raw * scale in double), then round half up to
    Q.frac, saturating (vh_skfq_quantise_inputs)."""
    r = math.floor(math.ldexp(raw * scale, frac) + 0.5)
    return max(I32_MIN, min(I32_MAX, r))


@pytest.mark.parametrize("sig", [s for s in CHS.signals if s.name in FRAC],
                         ids=lambda s: s.name)
def test_every_raw_value_reaches_the_filter_as_before(sig):
    frac = getattr(lib, "VH_SKFQ_" + FRAC[sig.name])
    dec = fn(CHS, sig, "decode_q")
    sat = ffi.new("uint32_t *")
    lo, hi = (-(2**15), 2**15 - 1) if sig.is_signed else (0, 2**16 - 1)
    bad = [raw for raw in range(lo, hi + 1) if dec(raw, frac, sat) != double_path(raw, sig.scale, frac)]
    assert bad == []


def test_the_ecu_sees_every_chassis_channel_through_the_integer_path():
    assert set(FRAC) == {s.name for s in CHS.signals if s.scale != 1}
    src = (ROOT / "c_core" / "tireforce" / "vh_tireforce_app.c").read_text()
    assert "vh_skfq_host.h" not in src and "quantise_inputs" not in src and "_decode(" not in src
    assert src.count("_decode_q(") >= 1 and src.count("TAKE(") == 14  # the macro and 13 channels


@settings(max_examples=500, deadline=None)
@given(st.integers(I32_MIN, I32_MAX))
def test_tyre_forces_go_out_as_before(fy):
    """Q.FN -> raw at 0.5 N, integer, equals the double encode it replaced."""
    for i in range(1, 5):
        sig = TFE.get_signal_by_name(f"Fy{i}")
        lo, hi, _ = dbcgen._raw_bounds(sig)
        want = max(lo, min(hi, math.floor(fy * 2.0**-lib.VH_SKFQ_FN / sig.scale + 0.5)))
        assert fn(TFE, sig, "encode_q")(fy, lib.VH_SKFQ_FN) == want


def test_from_raw_checks_its_preconditions():
    sat = ffi.new("uint32_t *")
    assert lib.vh_fix_from_raw(70000, 1, 1000, 24, sat) == 0 and sat[0] == 1
    assert lib.vh_fix_from_raw(1, 1, 1000, 31, sat) == 0 and sat[0] == 2
    assert lib.vh_fix_from_raw(1, 0, 1000, 24, sat) == 0 and sat[0] == 3
    assert lib.vh_fix_from_raw(-3, 1, 2, 0, sat) == -1 and sat[0] == 3  # floor(-1.5 + 0.5)
    assert lib.vh_fix_to_raw(5, 31, 1, 2) == 0 and lib.vh_fix_to_raw(5, 0, 1, 2**31 - 1) == 0


@pytest.mark.skipif(shutil.which("gcc") is None or os.uname().machine != "x86_64", reason="needs x86-64 gcc")
def test_the_conversions_are_integer_only(tmp_path):
    """Every generated raw <-> Q conversion of the chassis bus, and vh_fix.c behind them, compile
    under -mgeneral-regs-only (GCC refuses any floating point), like the filter itself."""
    gen = tmp_path / "gen"
    dbcgen.generate_all(gen)
    calls = [f"    acc += vh_ch_{dbcgen.camel_to_snake_case(m.name)}_{dbcgen.camel_to_snake_case(s.name)}_"
             f"{'decode_q(1, 20, &sat)' if m is CHS else 'encode_q(1, 14)'};"
             for m in (CHS, TFE) for s in m.signals if s.scale != 1]
    src = tmp_path / "use_q.c"
    src.write_text('#include "vh_ch_q.h"\nint64_t use(void);\nint64_t use(void)\n{\n    uint32_t sat = 0u;\n'
                   '    int64_t acc = 0;\n' + "\n".join(calls) + "\n    return acc + sat;\n}\n")
    for f in (src, vehest_build.firmware_path("vh_fix.c")):
        r = subprocess.run(["gcc", *vehest_build.STRICT_FLAGS, "-O2", "-mgeneral-regs-only",
                            f"-I{vehest_build.firmware_path('vh_fix.h').parent}", f"-I{gen}", "-c", str(f),
                            "-o", str(tmp_path / (f.stem + ".o"))], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
    assert len(calls) == 13 + 10
