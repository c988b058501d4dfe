"""Tire lateral force estimators (seed 000): SKFMEC double / fixed point and the plain EKF.

* the C double filter against the independent numpy reference (skf_ref.py);
* the fixed-point filter against the double one on synthetic manoeuvres (tests/tireforce/manoeuvres.py);
* saturation counting under a wheel-speed sensor stuck at its maximum; bit-exact determinism;
* the fixed-point helpers against Python integer arithmetic (hypothesis);
* "integer only": every translation unit of the tyre-force ECU path from raw CHS_Sensors to raw
  VEHEST_TireForceEst (the app, the filter, fixed point, RX/E2E, the generated pack/unpack)
  compiles with FP registers forbidden (host gcc -mgeneral-regs-only) and, for a soft-float
  Cortex-M, references no soft-float helper; a small file with one double in it fails both checks.
"""
import hashlib
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from manoeuvres import synthetic_manoeuvre

from vehest_can.errors import ConfigError, NativeError
from vehest_can.native import ffi, lib
from vehest_can.systems.tireforce import api as tf
from vehest_can.systems.tireforce import reference as skf_ref

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "c_core"))
import dbcgen  # noqa: E402

INCLUDE = ROOT / "c_core" / "common"
FIXED_SOURCES = [ROOT / "c_core" / "tireforce" / "vh_skfq.c", ROOT / "c_core" / "tireforce" / "vh_tfa.c",
                 ROOT / "c_core" / "common" / "vh_fix.c"]
I32_MIN, I32_MAX = -(2**31), 2**31 - 1


def short_profile(t):
    """1 Hz, 3 deg sine steer from 0.1 s with light braking: dynamics within a short reference run."""
    delta = math.radians(3.0 * math.sin(2 * math.pi * 1.0 * (t - 0.1))) if t > 0.1 else 0.0
    return delta, (-30.0, -30.0, -20.0, -20.0), 1.1


@pytest.fixture(scope="module")
def short_drive():
    return synthetic_manoeuvre(short_profile, duration=1.0, dm=200.0, seed=4)


@pytest.fixture(scope="module")
def drives():
    return {
        "paper": synthetic_manoeuvre("paper", duration=8.0, dm=200.0, seed=1),
        "ramp": synthetic_manoeuvre("ramp", duration=5.0, dm=0.0, seed=2),
        "sine": synthetic_manoeuvre("sine", duration=4.0, dm=0.0, seed=3),
    }


def normwise(a, ref):
    """Largest per-column |a - ref| relative to the column's peak |ref| (states cross zero)."""
    return float(np.max(np.abs(a - ref).max(axis=0) / np.maximum(np.abs(ref).max(axis=0), 1e-300)))


# ---- double precision against the numpy reference -------------------------------------------

@pytest.mark.parametrize("variant", [tf.SKFMEC, tf.EKF])
def test_c_double_equals_numpy_reference(short_drive, variant):
    _, inp = short_drive
    cfg = tf.SkfConfig.default(variant)
    run = tf.TireForceKF(cfg, variant).run(inp, covariances=True)
    ref = skf_ref.run(cfg, inp.ax, inp.ay, inp.r, inp.p, inp.delta, inp.omega, inp.torque)
    assert normwise(run.x, ref["x"]) < 1e-9
    assert normwise(run.fy, ref["fy"]) < 1e-9
    assert normwise(run.fz, ref["fz"]) < 1e-9
    diag = np.diagonal(run.p, axis1=1, axis2=2)
    assert normwise(diag, np.diagonal(ref["p"], axis1=1, axis2=2)) < 1e-9
    assert run.resets == 0 and np.all(run.health[400:] == lib.VH_HEALTH_OK)


def test_scaling_is_a_similarity_transform(short_drive):
    """Without the compensator, scaled and unscaled filters are the same filter (eq. 28); what S
    changes is the conditioning: P* is O(1) where P spans many decades."""
    _, inp = short_drive
    scaled = tf.TireForceKF(tf.SkfConfig.default(tf.SKFMEC, mec=False)).run(inp, covariances=True)
    plain = tf.TireForceKF(tf.SkfConfig.default(tf.EKF)).run(inp, covariances=True)
    assert normwise(scaled.x, plain.x) < 1e-9
    s = np.asarray(tf.SkfConfig.default().s)
    np.testing.assert_allclose(plain.p[-1] * np.outer(s, s), scaled.p[-1], rtol=1e-6, atol=1e-15)
    assert np.linalg.cond(plain.p[-1]) > 1e6 * np.linalg.cond(scaled.p[-1])


def test_model_is_consistent_with_its_own_steady_state():
    """zeta from vh_skf_zeta_steady: in steady cornering eq. 31-32 reproduce the roll equation."""
    cfg = tf.SkfConfig.default()
    ay = 3.0
    l = cfg.lf + cfg.lr
    fyf, fyr = cfg.m * ay * cfg.lr / (2 * l), cfg.m * ay * cfg.lf / (2 * l)
    phi = fyf / cfg.zeta1
    assert fyr / phi == pytest.approx(cfg.zeta2, rel=1e-12)
    kphi = cfg.kphif + cfg.kphir
    assert kphi * phi == pytest.approx(cfg.ms * cfg.e * ay + 2 * cfg.hf * fyf + 2 * cfg.hr * fyr, rel=1e-12)


def test_estimates_follow_the_synthetic_truth(drives):
    """Not a tuning claim, a sanity floor: per-tire RMS error on a dry-road ramp within 2% of peak."""
    truth, inp = drives["ramp"]
    for variant in (tf.SKFMEC, tf.EKF):
        run = tf.TireForceKF(variant=variant).run(inp)
        err = run.fy[400:] - truth["fy"][400:]
        assert np.sqrt((err**2).mean()) < 0.02 * np.abs(truth["fy"]).max(), variant


# ---- fixed point against double ---------------------------------------------------------------

@pytest.mark.parametrize("name", ["paper", "ramp", "sine"])
def test_fixed_point_matches_double(drives, name):
    _, inp = drives[name]
    cfg = tf.SkfConfig.default(tf.SKFMEC)
    dbl = tf.TireForceKF(cfg).run(inp)
    fix = tf.TireForceFixed(cfg).run(inp)
    peak = np.abs(dbl.fy).max()
    rms = np.sqrt(((fix.fy - dbl.fy) ** 2).mean(axis=0))
    print(f"{name}: fixed - double per-tire RMS = {np.round(rms / peak * 100, 4)} % of peak {peak:.0f} N")
    assert np.all(rms <= 0.005 * peak)  # acceptance: 0.5 % of peak |Fy|
    assert fix.saturations == 0 and fix.resets == 0 and dbl.resets == 0
    assert np.all(fix.health[400:] == lib.VH_HEALTH_OK)


def test_fixed_point_covariance_stays_symmetric_positive_definite(drives):
    _, inp = drives["paper"]
    fix = tf.TireForceFixed().run(inp, covariances=True)
    p = fix.p[::200]
    assert np.array_equal(p, np.transpose(p, (0, 2, 1)))
    assert np.min(np.linalg.eigvalsh(p)) > 0


def stuck_wheel(inp, k0, wheel=1):
    bad = tf.Inputs(**{k: np.array(getattr(inp, k), copy=True) for k in ("ax", "ay", "r", "p", "delta", "omega",
                                                                        "torque")})
    bad.omega[k0:, wheel] = 2.0**10  # the largest wheel speed the Q10.21 input can carry
    return bad


def test_wheel_speed_stuck_at_max_saturates_counts_and_survives(drives):
    _, inp = drives["sine"]
    k0 = 4000
    est = tf.TireForceFixed()
    run = est.run(stuck_wheel(inp, k0))
    nominal = tf.TireForceFixed().run(inp)
    assert np.array_equal(run.fy[:k0], nominal.fy[:k0])
    assert run.saturations >= 1 and est.saturations == run.saturations
    assert run.health[k0] == lib.VH_HEALTH_DEGRADED  # the saturating step is flagged
    assert run.resets == 0 and np.all(np.isfinite(run.fy))
    # the wheel-acceleration spike decays (tau 20 ms); a second later the estimate is nominal again
    assert np.abs(run.fy[-1] - nominal.fy[-1]).max() < 0.02 * np.abs(nominal.fy).max()


def test_saturation_of_an_out_of_range_state_is_counted():
    """A lateral acceleration the Q7.24 input cannot hold saturates at quantisation; one far beyond
    the force formats saturates inside the step: both counted, no crash."""
    q = np.zeros((50, 13), dtype=np.int32)
    q[:, 5:9] = int(63.7 * 2**21)
    q[:, 1] = I32_MAX  # ay = 128 m/s^2 for 50 steps
    est = tf.TireForceFixed()
    raw = est.run_raw(q)
    assert raw["saturations"] > 0
    assert np.all(raw["health"][1:] != lib.VH_HEALTH_OK)


def integer_drive(n=3000, seed=7):
    """Integer-only inputs (an LCG and integer ramps): the golden run cannot depend on libm."""
    state = seed
    q = np.empty((n, 13), dtype=np.int64)
    for t in range(n):
        state = (state * 6364136223846793005 + 1442695040888963407) % 2**64
        noise = ((state >> 33) % 2001) - 1000  # -1000..1000
        delta = (t * 2**30 // 20000) if t < 1500 else (2**30 * 1500 // 20000)  # up to ~0.075 rad
        q[t] = [noise * 800, delta // 12 + noise * 800, delta // 60 + noise * 2000, noise * 1500, delta,
                63 * 2**21 + noise * 40, 63 * 2**21 - noise * 40, 63 * 2**21 + noise * 30, 63 * 2**21,
                -30 * 2**16, -30 * 2**16, -20 * 2**16, -20 * 2**16]
    return q.astype(np.int32)


# sha256 of the integer filter's outputs on integer_drive() with the default configuration
GOLDEN = "0e21520d35af7dcddb908fcaff6041fbe9179dbc6f3530e5b2e1b046e37c298a"


def golden_digest():
    raw = tf.TireForceFixed().run_raw(integer_drive())
    h = hashlib.sha256()
    for key in ("x", "fy", "fz", "health"):
        h.update(np.ascontiguousarray(raw[key]).tobytes())
    h.update(str((raw["saturations"], raw["resets"])).encode())
    return h.hexdigest()


def test_unobservable_velocity_drift_is_clamped_not_reset():
    """vx, vy are seen by no output: an a_y bias with no yaw makes vy run away open loop. Both
    filters hold it at x_max instead of resetting the force estimates (90 s of a 2 m/s^2 bias)."""
    q = integer_drive(n=180_000)
    q[:, 1] = q[:, 1] // 4 + 2 * 2**24  # ay: +2 m/s^2 bias
    q[:, 2] = q[:, 2] // 16             # almost no yaw
    fix = tf.TireForceFixed()
    raw = fix.run_raw(q)
    assert raw["resets"] == 0 and raw["saturations"] == 0
    assert raw["x"][-1, 1] == fix.params.x_max  # vy* at the clamp
    assert np.all(raw["health"][400:] == lib.VH_HEALTH_OK)
    u = q.astype(float) / 2.0 ** np.array([24, 24, 27, 27, 30] + [21] * 4 + [16] * 4)
    inp = tf.Inputs(u[:, 0], u[:, 1], u[:, 2], u[:, 3], u[:, 4], u[:, 5:9], u[:, 9:13])
    dbl = tf.TireForceKF().run(inp)
    assert dbl.resets == 0 and dbl.x[-1, 1] * tf.SkfConfig.default().s[1] == pytest.approx(1000.0)


def test_fixed_point_is_bit_exact_and_deterministic(drives):
    _, inp = drives["sine"]
    est = tf.TireForceFixed()
    q = est.quantise(inp)
    a = est.run_raw(q)
    est.reset()
    b = est.run_raw(q)
    c = tf.TireForceFixed().run_raw(q)
    for key in ("x", "fy", "fz", "health"):
        assert np.array_equal(a[key], b[key]) and np.array_equal(a[key], c[key])


def test_fixed_point_golden_run():
    """Bit-exact regression of the integer filter: any change to its arithmetic changes this digest.
    Update GOLDEN only for an intended change (and say why in the commit)."""
    assert golden_digest() == GOLDEN


# ---- validity, health, configuration ----------------------------------------------------------

def test_missing_measurement_degrades_and_nan_does_not_crash(short_drive):
    _, inp = short_drive
    for est in (tf.TireForceKF(), tf.TireForceFixed()):
        mask = np.full(len(inp), lib.VH_SKF_ALL_VALID, dtype=np.uint8)
        mask[1000:1010] = lib.VH_SKF_ALL_VALID & ~lib.VH_SKF_Y_AY
        run = est.run(inp, mask)
        assert np.all(run.health[1000:1010] == lib.VH_HEALTH_DEGRADED)
        assert run.health[1500] == lib.VH_HEALTH_OK
    bad = inp.slice(0, 600)
    bad.ay = np.array(bad.ay, copy=True)
    bad.ay[500] = np.nan
    for est in (tf.TireForceKF(), tf.TireForceFixed()):
        run = est.run(bad)
        assert np.all(np.isfinite(run.x)) and run.health[500] == lib.VH_HEALTH_DEGRADED
        assert run.saturations == 0 and run.health[599] == lib.VH_HEALTH_OK


@pytest.mark.parametrize("bad", [dict(m=0.0), dict(ms=5000.0), dict(ts=float("nan")), dict(r=(1, 1, 0, 1)),
                                 dict(q=(1, 1, 1, 1, 1, 1, float("inf"))), dict(p_cap=2e6)])
def test_bad_configuration_is_refused(bad):
    with pytest.raises(NativeError, match="configuration"):
        tf.TireForceKF(tf.SkfConfig.default(**bad))


def test_fixed_point_refuses_what_it_cannot_represent():
    with pytest.raises(ConfigError, match="scaled"):
        tf.TireForceFixed(tf.SkfConfig.default(scaled=False))
    with pytest.raises(NativeError, match="fixed-point constants"):
        tf.TireForceFixed(tf.SkfConfig.default(q=(1e12,) * 7))
    with pytest.raises(ConfigError, match="unknown estimator setting"):
        tf.SkfConfig.default(gain=1)
    with pytest.raises(ConfigError, match="shape"):
        tf.TireForceKF().run(tf.Inputs(*(np.zeros(3),) * 5, np.zeros((3, 3)), np.zeros((3, 4))))
    prm = ffi.new("vh_skfq_params_t *")
    assert lib.vh_skfq_params_from_config(tf.SkfConfig.default().to_c(), prm) == lib.VH_OK
    prm.k_lf.m = 12345  # not normalised: a corrupted parameter set
    assert lib.vh_skfq_init(ffi.new("vh_skfq_t *"), prm) == lib.VH_EINVAL


# ---- fixed-point helpers against Python integers ------------------------------------------------

i32 = st.integers(I32_MIN, I32_MAX)
frac = st.integers(0, 31)


def sat32(v):
    return (max(I32_MIN, min(I32_MAX, v)), int(v < I32_MIN or v > I32_MAX))


def py_rshift_rnd(x, s):
    if s <= 0:
        return sat32(x)
    if s >= 63:
        return 0, 0
    return sat32((x + (1 << (s - 1))) >> s)  # Python >> floors: round half up


def call(fn, *args):
    sat = ffi.new("uint32_t *")
    return fn(*args, sat), sat[0]


@settings(max_examples=400, deadline=None)
@given(st.integers(-(2**62) + 1, 2**62 - 1), st.integers(-2, 64))
def test_rshift_rnd_rounds_half_up_and_saturates(x, s):
    assert call(lib.vh_fix_rshift_rnd, x, s) == py_rshift_rnd(x, s)


@settings(max_examples=400, deadline=None)
@given(i32, frac, i32, frac, st.integers(0, 31))
def test_mul_matches_integer_arithmetic(a, fa, b, fb, fo):
    if fo > fa + fb:
        fo = fa + fb
    assert call(lib.vh_fix_mul, a, fa, b, fb, fo) == py_rshift_rnd(a * b, fa + fb - fo)


@settings(max_examples=400, deadline=None)
@given(st.one_of(st.integers(2**30, 2**31 - 1), st.integers(-(2**31), -(2**30)), st.just(0)),
       st.integers(-10, 90), i32, frac, frac)
def test_kmul_matches_integer_arithmetic(m, e, v, fin, fout):
    k = ffi.new("vh_fix_k_t *", {"m": m, "e": e})[0]
    s = e + fin - fout
    expect = py_rshift_rnd(m * v, s) if s >= 0 else sat32(m * v * 2 ** (-s))
    assert call(lib.vh_fix_kmul, k, v, fin, fout) == expect


@settings(max_examples=300, deadline=None)
@given(i32, i32)
def test_add_sub_saturate(a, b):
    assert call(lib.vh_fix_add, a, b) == sat32(a + b)
    assert call(lib.vh_fix_sub, a, b) == sat32(a - b)


@settings(max_examples=300, deadline=None)
@given(i32, frac, frac)
def test_convert_between_formats(x, fin, fout):
    expect = sat32(x << (fout - fin)) if fout >= fin else py_rshift_rnd(x, fin - fout)
    assert call(lib.vh_fix_convert, x, fin, fout) == expect


@settings(max_examples=400, deadline=None)
@given(i32, i32, st.integers(0, 30))
def test_div_rounds_half_up(num, den, s):
    got = call(lib.vh_fix_div, num, den, s)
    if den <= 0:
        assert got == ((0, 0) if num == 0 else ((I32_MAX if num > 0 else I32_MIN), 1))
    else:
        assert got == sat32((2 * num * 2**s + den) // (2 * den))  # floor(num 2^s / den + 1/2)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.one_of(st.just(0), i32), i32), min_size=1, max_size=8), st.integers(1, 3))
def test_guarded_dot_never_overflows_and_skips_only_zeros(pairs, stride):
    """The packed row's product is the dense guarded sum, zeros in a included, b read with a stride."""
    a = ffi.new("int32_t[]", [p[0] for p in pairs])
    b = ffi.new("int32_t[]", [v for p in pairs for v in [p[1]] + [12345] * (stride - 1)])
    row = ffi.new("vh_fix_row_t *")
    lib.vh_fix_row_pack(a, len(pairs), row)
    assert row.n == sum(1 for x, _ in pairs if x != 0)
    assert lib.vh_fix_row_dot(row, b, stride) == sum((x * y) >> 3 for x, y in pairs)


@settings(max_examples=300, deadline=None)
@given(st.integers(-(2**30), 2**30))
def test_sincos_polynomial_accuracy(angle):
    s, c = ffi.new("int32_t *"), ffi.new("int32_t *")
    sat = ffi.new("uint32_t *")
    lib.vh_fix_sincos(angle, s, c, sat)
    x = angle / 2**30
    assert abs(s[0] / 2**30 - math.sin(x)) < 5e-8
    assert abs(c[0] / 2**30 - math.cos(x)) < 5e-8
    assert sat[0] == 0


def test_sincos_clips_and_counts_beyond_one_radian():
    s, c = ffi.new("int32_t *"), ffi.new("int32_t *")
    sat = ffi.new("uint32_t *")
    lib.vh_fix_sincos(2**30 + 1, s, c, sat)
    assert sat[0] == 1 and abs(s[0] / 2**30 - math.sin(1.0)) < 5e-8


def test_saturation_counter_itself_saturates():
    sat = ffi.new("uint32_t *", 2**32 - 1)
    assert lib.vh_fix_add(I32_MAX, 1, sat) == I32_MAX and sat[0] == 2**32 - 1


# ---- integer only ---------------------------------------------------------------------------

NEGATIVE = "int scale(int a)\n{\n    double x = a;\n    return (int)(x * 1.5);\n}\n"
# soft-float helpers of the ARM EABI and libgcc, and the libm entry points
SOFT_FLOAT = re.compile(r"^(__aeabi_(?:[fd]\w*|\w*2[fd]\w*)|__\w+[sdt]f\d?|__\w+[sdt]f[sdt]f\d?|"
                        r"(?:sin|cos|tan|sqrt|exp|log|pow|floor|ceil|fabs|frexp|ldexp|fmod|round)f?)$")


def tyre_force_path(tmp: Path) -> tuple[list[Path], list[Path], Path]:
    """The tyre-force ECU path from raw frame to raw frame, as translation units: the app (RX,
    step, TX), the fixed-point filters (SKFMEC and SKFMEC-A), the fixed-point helpers, RX checks and E2E; their include
    folders; and the chassis bus's generated codec (vh_ch.c), which is checked per function (it
    also holds cantools' double ``_encode``/``_decode`` helpers, which no firmware calls on this bus)."""
    gen = tmp / "gen"
    dbcgen.generate_all(gen)
    srcs = [ROOT / "c_core" / "tireforce" / "vh_tireforce_app.c", *FIXED_SOURCES,
            ROOT / "c_core" / "common" / "vh_rx.c", ROOT / "c_core" / "common" / "vh_e2e.c"]
    return srcs, [gen, INCLUDE, ROOT / "c_core" / "tireforce"], gen / "vh_ch.c"


def arm_relocations(obj: Path) -> dict[str, set[str]]:
    """Per function (built with -ffunction-sections): the symbols its code refers to."""
    out = subprocess.run(["arm-none-eabi-objdump", "-r", str(obj)], check=True, capture_output=True, text=True).stdout
    refs: dict[str, set[str]] = {}
    cur = None
    for line in out.splitlines():
        m = re.match(r"RELOCATION RECORDS FOR \[\.text\.(\w+)\]:", line)
        if m:
            cur = refs.setdefault(m.group(1), set())
        elif cur is not None and re.match(r"^[0-9a-f]{8} ", line):
            cur.add(line.split()[-1].split("+")[0])
    return refs


def host_general_regs_only(src: Path, tmp: Path, inc: list[Path] = (INCLUDE,)) -> subprocess.CompletedProcess:
    return subprocess.run(["gcc", "-std=c99", "-O2", "-mgeneral-regs-only", *(f"-I{d}" for d in inc), "-c", str(src),
                           "-o", str(tmp / (src.stem + ".o"))], capture_output=True, text=True)


def arm_object(src: Path, tmp: Path, inc: list[Path] = (INCLUDE,)) -> Path:
    obj = tmp / (src.stem + ".arm.o")
    subprocess.run(["arm-none-eabi-gcc", "-std=c99", "-ffreestanding", "-O2", "-mcpu=cortex-m3", "-mthumb",
                    "-mfloat-abi=soft", *(f"-I{d}" for d in inc), "-c", str(src), "-o", str(obj)],
                   check=True, capture_output=True, text=True)
    return obj


def undefined(obj: Path, nm: str) -> list[str]:
    out = subprocess.run([nm, "-u", str(obj)], check=True, capture_output=True, text=True).stdout
    return [line.split()[-1] for line in out.splitlines() if line.strip()]


def arm_soft_float_symbols(src: Path, tmp: Path, inc: list[Path] = (INCLUDE,)) -> list[str]:
    return [sym for sym in undefined(arm_object(src, tmp, inc), "arm-none-eabi-nm") if SOFT_FLOAT.match(sym)]


@pytest.mark.rebuild
@pytest.mark.skipif(shutil.which("gcc") is None or os.uname().machine != "x86_64", reason="needs x86-64 gcc")
def test_fixed_point_units_compile_without_fp_registers(tmp_path):
    """GCC refuses any floating-point use under -mgeneral-regs-only: every unit of the tyre-force
    path from raw CHS_Sensors to raw VEHEST_TireForceEst builds, a one-double file does not (so the
    check can fail). The generated codec holds double helpers, so it is checked per function on the
    Cortex-M build below."""
    srcs, inc, _ = tyre_force_path(tmp_path)
    for src in srcs:
        res = host_general_regs_only(src, tmp_path, inc)
        assert res.returncode == 0, src.name + res.stderr
    neg = tmp_path / "uses_double.c"
    neg.write_text(NEGATIVE)
    res = host_general_regs_only(neg, tmp_path)
    assert res.returncode != 0 and "SSE" in res.stderr


@pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None and os.environ.get("CI", "").lower() not in ("true", "1"),
                    reason="needs gcc-arm-none-eabi (Debian package gcc-arm-none-eabi; CI installs it and "
                           "fails here without it)")
@pytest.mark.rebuild
def test_fixed_point_units_need_no_soft_float_on_cortex_m(tmp_path):
    """Built for a Cortex-M3 (no FPU, soft-float ABI), the tyre-force path's units (as above)
    reference no __aeabi_f*/__aeabi_d* or libgcc/libm float routine; the one-double file does.
    Of the generated codec, the app uses only pack/unpack and the E2E table (its undefined vh_ch_
    symbols: vh_ch_e2e_cfgs is data), and those
    functions and everything they call refer to no soft-float routine, where the codec's double
    helpers beside them do (so this part can fail too)."""
    srcs, inc, codec = tyre_force_path(tmp_path)
    for src in srcs:
        assert arm_soft_float_symbols(src, tmp_path, inc) == [], src.name
    calls = {s for s in undefined(tmp_path / "vh_tireforce_app.arm.o", "arm-none-eabi-nm") if s.startswith("vh_ch_")}
    assert calls == {"vh_ch_chs_sensors_unpack", "vh_ch_chs_ride_height_unpack", "vh_ch_vehest_tire_force_est_pack",
                     "vh_ch_vehest_chassis_status_pack", "vh_ch_vehest_tire_force_adaptive_pack", "vh_ch_e2e_cfgs"}
    calls.discard("vh_ch_e2e_cfgs")
    obj = tmp_path / "vh_ch.arm.o"
    subprocess.run(["arm-none-eabi-gcc", "-std=c99", "-ffreestanding", "-O2", "-mcpu=cortex-m3", "-mthumb",
                    "-mfloat-abi=soft", "-ffunction-sections", *(f"-I{d}" for d in inc), "-c", str(codec), "-o", str(obj)],
                   check=True, capture_output=True, text=True)
    refs = arm_relocations(obj)
    seen, todo = set(), set(calls)
    while todo:
        fn = todo.pop()
        seen.add(fn)
        todo |= {r for r in refs.get(fn, ()) if r in refs} - seen
    assert [r for fn in seen for r in refs.get(fn, ()) if SOFT_FLOAT.match(r)] == []
    assert any(SOFT_FLOAT.match(r) for r in refs["vh_ch_vehest_tire_force_est_fyf_encode"])
    neg = tmp_path / "uses_double.c"
    neg.write_text(NEGATIVE)
    assert arm_soft_float_symbols(neg, tmp_path) != []


def build_bench(tmp: Path, name: str, flags: list[str]) -> Path:
    exe = tmp / name
    sources = [ROOT / "c_core" / "bench" / "vh_bench_skf.c"] + [ROOT / "c_core" / f for f in (
        "tireforce/vh_skf.c", "tireforce/vh_skfq.c", "tireforce/vh_skfq_host.c", "tireforce/vh_tfa.c",
        "tireforce/vh_tfa_host.c", "common/vh_fix.c")]
    build = subprocess.run(["cc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", *flags, f"-I{INCLUDE}",
             f"-I{INCLUDE.parent / 'tireforce'}",
                            *map(str, sources), "-lm", "-o", str(exe)], capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    return exe


def run_bench(exe: Path) -> dict:
    run = subprocess.run([str(exe), "3000"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "runtime error" not in run.stderr
    return {line.split()[0]: line.split()[1:] for line in run.stdout.splitlines()}


@pytest.mark.rebuild
@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_estimators_under_sanitizers_and_bit_exact_across_builds(tmp_path):
    """libfixmath practice: the fixed-point code (shifts of negative values, int64 products) and
    the double filters run clean under UBSan + ASan. The driver is the C-loop benchmark
    (c_core/bench/vh_bench_skf.c, also what tools.bench.bench_c_loop builds), so this also shows the
    benchmark entry works. The fixed filter's final state is the same, bit for bit, in the
    sanitized -O1 build and a plain -O3 build, the SKFMEC's and SKFMEC-A's (with the road's friction
    updating from step 2000 on: the sine's |a_y| reaches 4.9 m/s^2 on free-rolling wheels)."""
    san = run_bench(build_bench(tmp_path, "skf_san", ["-O1", "-g", "-fsanitize=address,undefined",
                                                      "-fno-sanitize-recover=all"]))
    fast = run_bench(build_bench(tmp_path, "skf_o3", ["-O3"]))
    assert {"skfmec_double_step", "ekf_double_step", "skfmec_fixed_step"} <= set(san)
    assert san["skfmec_fixed_saturations"][0] == "0" and san["skfmec_a_fixed_saturations"][0] == "0"
    assert "skfmec_a_fixed_step" in san
    assert san["skfmec_fixed_checksum"] == fast["skfmec_fixed_checksum"]
    assert san["skfmec_a_fixed_checksum"] == fast["skfmec_a_fixed_checksum"]
