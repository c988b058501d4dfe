"""Safe edges of the C core: preconditions that are checked, not assumed (issue 10, item 7).

* the guarded dot product refuses n outside [0, 8]; vh_fix_lshift_sat is defined for any shift; vh_fix_div's
  clamp of s is counted;
* the generated TX encoders round half up, clamp to the DBC range and send SNA (or 0) for NaN,
  where a plain (int16_t) cast would be undefined behaviour;
* a DBC cycle time that is not a whole number of ticks does not build;
* a gear change in the tick copies a model discretised at init, bit-identical to discretising.
"""
import math
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
import firmware_size  # noqa: E402
import vehest_build  # noqa: E402

I32_MIN, I32_MAX = -(2**31), 2**31 - 1


def sat_call(fn, *args):
    sat = ffi.new("uint32_t *")
    return fn(*args, sat), sat[0]


# ---- fixed point ------------------------------------------------------------------------------

def dot(a, b, n, sb=1):
    row = ffi.new("vh_fix_row_t *")
    lib.vh_fix_row_pack(a, n, row)
    return lib.vh_fix_row_dot(row, b, sb)


def test_dot_refuses_more_terms_than_its_accumulator_holds():
    a = ffi.new("int32_t[]", [I32_MAX] * 9)
    assert lib.VH_FIX_DOT_MAX == 8
    assert dot(a, a, 8) == 8 * ((I32_MAX * I32_MAX) >> 3)
    assert dot(a, a, 9) == 0
    assert dot(a, a, -1) == 0
    assert dot(a, a, 0) == 0


@settings(max_examples=300, deadline=None)
@given(st.integers(I32_MIN, I32_MAX), st.integers(-70, 70))
def test_lshift_is_defined_for_any_shift(x, s):
    got = sat_call(lib.vh_fix_lshift_sat, x, s)
    if s >= 0:
        exact = x * 2**s
        want = (max(I32_MIN, min(I32_MAX, exact)), int(not I32_MIN <= exact <= I32_MAX))
    else:
        want = sat_call(lib.vh_fix_rshift_rnd, x, -s)
    assert got == want


@pytest.mark.parametrize("s", [-1, 31, 40])
def test_div_counts_a_clamped_shift(s):
    clamped = min(max(s, 0), 30)
    got, sat = sat_call(lib.vh_fix_div, 3, 7, s)
    assert got == (2 * 3 * 2**clamped + 7) // 14 and sat == 1
    assert sat_call(lib.vh_fix_div, 3, 7, 30)[1] == 0


# ---- TX encoders ------------------------------------------------------------------------------

def _encoders():
    for bus in ("pt", "ch"):
        db = cantools.database.load_file(str(ROOT / "dbc" / f"vehest_{bus}.dbc"))
        for m in db.messages:
            for s in m.signals:
                if s.scale == 1 and s.offset == 0:
                    continue
                name = f"vh_{bus}_{dbcgen.camel_to_snake_case(m.name)}_{dbcgen.camel_to_snake_case(s.name)}"
                yield getattr(lib, name + "_encode_round"), s


ENCODERS = list(_encoders())


def test_every_scaled_signal_has_an_encoder():
    assert len(ENCODERS) >= 40


@pytest.mark.parametrize("enc,sig", ENCODERS, ids=[s.name for _, s in ENCODERS])
def test_encoder_nan_and_range(enc, sig):
    lo, hi, sna = dbcgen._raw_bounds(sig)
    assert enc(math.nan) == (sna if sna is not None else 0)
    assert enc(math.inf) == hi and enc(-math.inf) == lo
    assert enc(1e300) == hi and enc(-1e300) == lo
    assert lo == round(sig.minimum / sig.scale) and hi == round(sig.maximum / sig.scale)


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(range(len(ENCODERS))), st.floats(-1e5, 1e5, allow_nan=False))
def test_encoder_rounds_half_up_like_the_firmware_did(i, v):
    """raw = floor(v / scale + 0.5) clamped: the hand-written enc_s16/enc_u16 it replaces."""
    enc, sig = ENCODERS[i]
    lo, hi, _ = dbcgen._raw_bounds(sig)
    assert enc(v) == max(lo, min(hi, math.floor(v / sig.scale + 0.5)))


# ---- cycle times ------------------------------------------------------------------------------

@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_a_cycle_time_that_is_not_whole_ticks_does_not_build(tmp_path):
    db = cantools.database.load_file(str(ROOT / "dbc" / "vehest_pt.dbc"))
    meta = dbcgen.meta_header(db, "vh_pt")
    line = "#define VH_PT_VEHEST_STATUS_CYCLE_TIME_US (10000u)"
    assert line in meta
    (tmp_path / "ok_meta.h").write_text(meta)
    (tmp_path / "vh_pt_e2e.h").write_text(dbcgen.e2e_header(db, "vh_pt"))  # the meta header includes it
    (tmp_path / "seven_meta.h").write_text(meta.replace(line, line.replace("10000u", "7000u")))  # 14 ticks
    (tmp_path / "bad_meta.h").write_text(meta.replace(line, line.replace("10000u", "750u")))  # 1.5 ticks

    def build(header):
        src = tmp_path / f"use_{header}.c"
        src.write_text(f'#include "{header}"\nint main(void) {{ return 0; }}\n')
        return subprocess.run(["cc", *vehest_build.STRICT_FLAGS, f"-I{ROOT / 'c_core' / 'common'}", f"-I{tmp_path}",
                               "-c", str(src), "-o", str(tmp_path / "x.o")], capture_output=True, text=True)

    assert build("ok_meta.h").returncode == 0
    assert build("seven_meta.h").returncode == 0
    bad = build("bad_meta.h")
    assert bad.returncode != 0 and "vh_pt_vehest_status_cycle_is_whole_ticks" in bad.stderr


# ---- gear change ------------------------------------------------------------------------------

def test_gear_model_at_init_equals_discretising_in_the_tick():
    for disc in (lib.VH_DKF_ZOH, lib.VH_DKF_EULER):
        cfg = ffi.new("vh_dkf_config_t *")
        lib.vh_dkf_config_default(cfg, lib.VH_DKF_SPEEDS_TORQUE)
        cfg.disc = disc
        f, g = ffi.new("vh_dkf_t *"), ffi.new("vh_dkf_t *")
        assert lib.vh_dkf_init(f, cfg) == lib.VH_OK and lib.vh_dkf_init(g, cfg) == lib.VH_OK
        for ri in (0.28, 0.43, 0.66, 0.91, 1.18):
            m = ffi.new("vh_dkf_gear_model_t *")
            assert lib.vh_dkf_gear_model(cfg, ri, m) == lib.VH_OK
            assert lib.vh_dkf_set_ratio(f, ri) == lib.VH_OK
            lib.vh_dkf_use_gear_model(g, m)
            assert ffi.buffer(f.ad)[:] == ffi.buffer(g.ad)[:] and ffi.buffer(f.bd)[:] == ffi.buffer(g.bd)[:]
            assert g.cfg.ri == ri
        assert lib.vh_dkf_gear_model(cfg, 0.0, ffi.new("vh_dkf_gear_model_t *")) == lib.VH_EINVAL


@pytest.mark.rebuild
@pytest.mark.skipif(firmware_size.missing_toolchain() is not None, reason=str(firmware_size.missing_toolchain()))
def test_the_tick_computes_no_matrix_exponential():
    """In the call graph of the Cortex-M4 build, vh_ecu_step reaches no vh_mat_expm (a gear change
    copies a model), while vh_ecu_init_params does (it discretises every gear)."""
    graph = firmware_size.call_graph()
    assert "vh_mat_expm" in firmware_size.reachable(graph, "vh_ecu_init_params")
    tick = firmware_size.reachable(graph, "vh_ecu_step") | firmware_size.reachable(graph, "vh_ecu_rx")
    assert "vh_mat_expm" not in tick and "vh_dkf_set_ratio" not in tick
