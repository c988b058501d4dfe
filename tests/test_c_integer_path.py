"""The tyre-force ECU application's integer path (issue 10, item 5): raw frame to raw frame.

CHS_Sensors raw signals reach the fixed-point SKFMEC by an exact integer scaling (the DBC scale as
a fraction, generated vh_ch_q.h): checked here against the double path it replaced (decode in
double, then round to the Q format) for every raw value of every signal, so the ECU's inputs are
the same integers as before. The tyre forces Fy1..Fy4 go out the same way (Q.FN -> raw, exact), and
the six states (Fyf, Fyr, vx, vy, r, phi) through ``..._encode_qs``: the DBC's fraction times the
filter's scaling S as an exact fraction (vh_skfq_params_t.s_num/s_den). The soft-float check of the
whole path is in tests/tireforce/test_tireforce_filters.py.
"""
import math
import os
import re
import shutil
import subprocess
import sys
from fractions import Fraction
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
    code = re.sub(r"/\*.*?\*/", "", src, flags=re.S)
    assert not re.search(r"\b(double|float)\b", code) and "math.h" not in code and "_enc.h" not in code


STATES = {"Fyf": 5, "Fyr": 6, "EstVx": 0, "EstVy": 1, "EstYawRate": 2, "EstRollAngle": 3}


@settings(max_examples=300, deadline=None)
@given(st.integers(I32_MIN, I32_MAX), st.sampled_from(sorted(STATES)),
       st.sampled_from([(1, 10), (10, 1), (1000, 1), (100, 1), (1, 1000), (3, 7), (1, 1)]))
def test_states_go_out_by_one_exact_rounding(v, name, s):
    """x* in Q.FX scaled by s = num/den -> raw: floor(x* / (2^FX s scale) + 1/2), clamped; exact."""
    sig = TFE.get_signal_by_name(name)
    lo, hi, _ = dbcgen._raw_bounds(sig)
    exact = Fraction(v) / (Fraction(2**lib.VH_SKFQ_FX) * Fraction(*s) * Fraction(repr(sig.scale)))
    assert fn(TFE, sig, "encode_qs")(v, lib.VH_SKFQ_FX, *s) == max(lo, min(hi, math.floor(exact + Fraction(1, 2))))


def test_scaling_is_an_exact_fraction_or_refused():
    """The calibration tool turns each s_i into the shortest fraction with that exact double (the
    paper's S: 1/10, 10, 10, 1000, 100, 1/1000, 1/1000); an s with no short fraction is refused,
    and an ECU whose S times a state's DBC scale does not fit the integer TX does not start."""
    from vehest_can.systems.tireforce import api as tf
    prm = ffi.new("vh_skfq_params_t *")
    cfg = tf.SkfConfig.default()
    assert lib.vh_skfq_params_from_config(cfg.to_c(), prm) == lib.VH_OK
    assert [Fraction(n, d) for n, d in zip(prm.s_num, prm.s_den)] == [Fraction(repr(x)) for x in cfg.s]
    assert [(n, d) for n, d in zip(prm.s_num, prm.s_den)] == [(1, 10), (10, 1), (10, 1), (1000, 1), (100, 1),
                                                              (1, 1000), (1, 1000)]
    odd = cfg.to_c()
    odd.s[3] = math.pi * 100
    assert lib.vh_skfq_params_from_config(odd, prm) == lib.VH_EINVAL
    assert lib.vh_ch_vehest_tire_force_est_est_roll_angle_qs_ok(1000, 1)
    assert not lib.vh_ch_vehest_tire_force_est_est_roll_angle_qs_ok(1, 100000)  # den 10^10 > 2^30
    assert lib.vh_ch_vehest_tire_force_est_est_roll_angle_encode_qs(2**21, 21, 1, 100000) == 0


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
