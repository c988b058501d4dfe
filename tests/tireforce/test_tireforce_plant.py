"""14-DOF chassis plant (vh_veh14), its Magic Formula tyre (vh_mftire), the chassis sensor node
(vh_chsnode), the chassis DBC and the chassis scenarios, through cffi.

The references are independent of the C code: the Magic Formula and its combined-slip rule
recomputed in numpy from the published coefficients with the peaks found by scipy, the linear
bicycle model's yaw-rate gain, the deceleration of a braked rigid car with spinning wheels, a
steady roll balance solved with numpy, energy bookkeeping, frames decoded by cantools.
"""
from __future__ import annotations

import math
import shutil
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import cantools
import e2e.p01
import numpy as np
import pytest
from cantools.database.can.c_source import camel_to_snake_case
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import optimize

from vehest_can.bus.busload import bus_load
from vehest_can.cli import main as cli_main
from vehest_can.errors import ScenarioError
from vehest_can.native import ffi, lib
from vehest_can.sim.veh14 import Veh14Scenario, truth_to_numpy
from vehest_can.systems.driveline.scenario import driveline_scenario_dir, list_driveline_scenarios, load_driveline_scenario
from vehest_can.systems.tireforce.scenario import list_tireforce_scenarios, load_tireforce_scenario, tireforce_scenario_dir

ROOT = Path(__file__).resolve().parents[2]
DT = 0.0005
G = 9.81
DEG = math.pi / 180

# Bakker, Nyborg & Pacejka 1987 (SAE 870421), the passenger-car tyre: Fz in kN, alpha in deg, kappa in %.
A = [1.30, -22.1, 1011.0, 1078.0, 1.82, 0.208, 0.000, -0.354, 0.707]
B = [1.65, -21.3, 1144.0, 49.6, 226.0, 0.069, -0.006, 0.056, 0.486]
FZ_SCALE = 1.75  # the plant's tyre size (docs/chassis_plant.md)


# ---- numpy reference of the documented tyre --------------------------------------------------

def mf(b, c, d, e, x):
    bx = b * x
    return d * np.sin(c * np.arctan(bx - e * (bx - np.arctan(bx))))


def ref_tyre(fz, mu, s=1.0):
    """B, C, D, E (slips in rad and as a fraction) and the pure-slip peaks found by scipy."""
    f = fz / 1000.0 / s
    t = dict(cy=A[0], cx=B[0])
    t["dy"] = s * mu / (A[2] / 1000) * (A[1] * f * f + A[2] * f)
    t["dx"] = s * mu / (B[2] / 1000) * (B[1] * f * f + B[2] * f)
    t["ky"] = s * A[3] * math.sin(A[4] * math.atan(A[5] * f)) * 180 / math.pi   # N/rad
    t["kx"] = s * (B[3] * f * f + B[4] * f) * math.exp(-B[5] * f) * 100          # N per unit slip
    t["ey"] = A[6] * f * f + A[7] * f + A[8]
    t["ex"] = B[6] * f * f + B[7] * f + B[8]
    t["by"] = t["ky"] / (t["cy"] * t["dy"])
    t["bx"] = t["kx"] / (t["cx"] * t["dx"])
    fy0 = lambda a: mf(t["by"], t["cy"], t["dy"], t["ey"], a)  # noqa: E731
    fx0 = lambda k: mf(t["bx"], t["cx"], t["dx"], t["ex"], k)  # noqa: E731
    opts = dict(method="bounded", options={"xatol": 1e-13})
    t["alpha_m"] = optimize.minimize_scalar(lambda a: -fy0(a), bounds=(1e-5, 1.4), **opts).x
    t["kappa_m"] = optimize.minimize_scalar(lambda k: -fx0(k), bounds=(1e-6, 0.9), **opts).x
    t["fy0"], t["fx0"] = fy0, fx0
    return t


def ref_combined(t, kappa, alpha):
    """Bakker, Pacejka & Lidner 1989 normalised theoretical slip, as documented in vh_mftire.h."""
    opk = max(1.0 + kappa, 1e-6)
    sx, sy = kappa / opk, math.tan(alpha) / opk
    km = t["kappa_m"]
    sxm = km / (1 + km) if sx >= 0 else km / (1 - km)
    sym = math.tan(t["alpha_m"])
    nx, ny = sx / sxm, sy / sym
    sn = math.hypot(nx, ny)
    if sn == 0.0:
        return 0.0, 0.0
    se = sn * sxm
    keq = se / (1 - se) if sx >= 0 else se / (1 + se)
    return nx / sn * t["fx0"](keq), ny / sn * t["fy0"](math.atan(sn * sym))


def coef(s=1.0):
    c = ffi.new("vh_mft_coef_t *")
    lib.vh_mft_coef_default(c)
    c.fz_scale = s
    return c


def tyre_eval(fz, mu, kappa, alpha, s=1.0):
    fx, fy = ffi.new("double *"), ffi.new("double *")
    lib.vh_mft_eval(coef(s), fz, mu, kappa, math.tan(alpha), fx, fy)
    return fx[0], fy[0]


def tyre_state(fz, mu, s=1.0):
    st_ = ffi.new("vh_mft_state_t *")
    lib.vh_mft_load(st_, coef(s), fz, mu)
    lib.vh_mft_peaks(st_, 0.0, 0.0, 0)
    return st_


# ---- plant helpers ---------------------------------------------------------------------------

def params(**over):
    prm = ffi.new("vh_v14_params_t *")
    lib.vh_v14_params_default(prm)
    for k, v in over.items():
        setattr(prm, k, v)
    return prm


def plant(v0=0.0, **over):
    p = ffi.new("vh_v14_t *")
    assert lib.vh_v14_init(p, params(**over)) == lib.VH_OK
    assert lib.vh_v14_set_rolling(p, v0) == lib.VH_OK
    return p


def inputs(n, steer=0.0, drive=(0, 0, 0, 0), brake=(0, 0, 0, 0), mu=(1.0, 1.0, 1.0, 1.0)):
    arr = np.zeros((n, 13))
    arr[:, 0] = steer
    arr[:, 1:5] = drive
    arr[:, 5:9] = brake
    arr[:, 9:13] = mu
    c = ffi.new("vh_v14_input_t[]", n)
    ffi.memmove(c, np.ascontiguousarray(arr).tobytes(), arr.nbytes)
    return c


def run(p, n, **kw):
    out = ffi.new("vh_v14_truth_t[]", n)
    assert lib.vh_v14_run(p, n, inputs(n, **kw), out) == n
    return truth_to_numpy(ffi, out, n)


# ---- tyre: the formula and its known properties ---------------------------------------------

def test_default_tyre_is_the_published_1987_set():
    c = coef()
    assert list(c.a) == A and list(c.b) == B and c.fz_scale == 1.0
    assert lib.vh_mft_check(c) == 1
    assert params().tyre.fz_scale == FZ_SCALE


@pytest.mark.parametrize("s", [1.0, FZ_SCALE])
@pytest.mark.parametrize("mu", [0.2, 1.1])
@pytest.mark.parametrize("fz", [1500.0, 4000.0, 7500.0])
def test_pure_slip_is_the_magic_formula(fz, mu, s):
    t = ref_tyre(fz, mu, s)
    for alpha in np.linspace(-0.5, 0.5, 41):
        fx, fy = tyre_eval(fz, mu, 0.0, alpha, s)
        assert fx == 0.0
        assert fy == pytest.approx(t["fy0"](alpha), rel=1e-12, abs=1e-9)
    for kappa in np.linspace(-0.6, 0.6, 41):
        fx, fy = tyre_eval(fz, mu, kappa, 0.0, s)
        assert fy == 0.0
        assert fx == pytest.approx(t["fx0"](kappa), rel=1e-12, abs=1e-9)


@pytest.mark.parametrize("mu", [0.2, 0.6, 1.1])
@pytest.mark.parametrize("fz", [1000.0, 3000.0, 5300.0, 9000.0])
def test_pure_slip_peak_slope_symmetry(fz, mu):
    t = ref_tyre(fz, mu, FZ_SCALE)
    s = tyre_state(fz, mu, FZ_SCALE)
    # peak = mu-scaled D, where scipy finds it; D never exceeds mu Fz
    assert tyre_eval(fz, mu, 0.0, t["alpha_m"], FZ_SCALE)[1] == pytest.approx(t["dy"], rel=1e-12)
    assert tyre_eval(fz, mu, t["kappa_m"], 0.0, FZ_SCALE)[0] == pytest.approx(t["dx"], rel=1e-12)
    assert s.alpha_m == pytest.approx(t["alpha_m"], rel=1e-6)
    assert s.kappa_m == pytest.approx(t["kappa_m"], rel=1e-6)
    assert t["dy"] <= mu * fz and t["dx"] <= mu * fz
    assert s.dy == pytest.approx(mu * fz * (1 + A[1] / A[2] * fz / 1000 / FZ_SCALE), rel=1e-12)
    # slope at zero slip = BCD (cornering / longitudinal slip stiffness), independent of mu
    h = 1e-7
    assert tyre_eval(fz, mu, 0.0, h, FZ_SCALE)[1] / h == pytest.approx(t["ky"], rel=1e-6)
    assert tyre_eval(fz, mu, h, 0.0, FZ_SCALE)[0] / h == pytest.approx(t["kx"], rel=1e-5)
    # zero at zero slip, odd in the slip
    assert tyre_eval(fz, mu, 0.0, 0.0, FZ_SCALE) == (0.0, 0.0)
    for x in (0.01, 0.05, 0.2):
        assert tyre_eval(fz, mu, 0.0, -x)[1] == -tyre_eval(fz, mu, 0.0, x)[1]
        # (kappa goes through sigma = kappa / (1 + kappa) and back: an ulp of rounding)
        assert tyre_eval(fz, mu, -x, 0.0)[0] == pytest.approx(-tyre_eval(fz, mu, x, 0.0)[0], rel=1e-13)
        for k in (-x, x):  # combined: mirrored slip angle mirrors the lateral force only
            fx, fy = tyre_eval(fz, mu, k, x)
            assert tyre_eval(fz, mu, k, -x) == (fx, -fy)


def test_combined_slip_matches_the_reference():
    rng = np.random.default_rng(3)
    for _ in range(300):
        fz, mu = rng.uniform(500, 9000), rng.uniform(0.1, 1.3)
        kappa, alpha = rng.uniform(-0.99, 1.0), rng.uniform(-0.6, 0.6)
        t = ref_tyre(fz, mu, FZ_SCALE)
        fx, fy = tyre_eval(fz, mu, kappa, alpha, FZ_SCALE)
        rx, ry = ref_combined(t, kappa, alpha)
        assert fx == pytest.approx(rx, rel=1e-6, abs=1e-6 * fz)
        assert fy == pytest.approx(ry, rel=1e-6, abs=1e-6 * fz)


def test_combined_slip_friction_ellipse_and_reduction():
    fz, mu = 5000.0, 1.0
    s = tyre_state(fz, mu, FZ_SCALE)
    kap = np.concatenate([-np.geomspace(1e-4, 0.999, 120), np.geomspace(1e-4, 3.0, 120)])
    alp = np.linspace(-0.6, 0.6, 61)
    worst = 0.0
    for k in kap:
        for a in alp:
            fx, fy = tyre_eval(fz, mu, k, a, FZ_SCALE)
            e = (fx / s.dx) ** 2 + (fy / s.dy) ** 2
            worst = max(worst, e)
            assert math.hypot(fx, fy) <= mu * fz
    assert worst <= 1 + 1e-12
    # on the contour where both normalised slips reach their peaks together, the ellipse is met
    km, am = s.kappa_m, s.alpha_m
    for w in np.linspace(0.05, 0.95, 7):
        # normalised theoretical slips (w, sqrt(1 - w^2)) on the braking side
        sxm, sym = km / (1 - km), math.tan(am)
        sx, syn = -w * sxm, math.sqrt(1 - w * w) * sym
        kappa = sx / (1 - sx)                 # sigma_x = kappa / (1 + kappa)
        alpha = math.atan(syn * (1 + kappa))  # sigma_y = tan(alpha) / (1 + kappa)
        fx, fy = tyre_eval(fz, mu, kappa, alpha, FZ_SCALE)
        assert (fx / s.dx) ** 2 + (fy / s.dy) ** 2 == pytest.approx(1.0, rel=1e-9)
    # braking at a fixed slip angle: the lateral force gives way as the longitudinal one grows
    a = 4 * DEG
    fy0 = tyre_eval(fz, mu, 0.0, a, FZ_SCALE)[1]
    ks = -np.geomspace(0.02, 0.99, 40)
    fys = [tyre_eval(fz, mu, k, a, FZ_SCALE)[1] for k in ks]
    fxs = [tyre_eval(fz, mu, k, a, FZ_SCALE)[0] for k in ks]
    assert all(np.diff(fys) < 0) and fys[0] < fy0
    assert fys[-1] < 0.35 * fy0 and -min(fxs) > 0.9 * s.dx
    # locked wheel: sliding friction (the curve's value at kappa = -1), the force nearly opposite
    # the sliding velocity (within the normalisation's distortion)
    fx, fy = tyre_eval(fz, mu, -1.0, a, FZ_SCALE)
    assert math.hypot(fx, fy) == pytest.approx(-lib.vh_mft_fx0(s, -1.0), rel=0.01)
    assert math.atan2(fy, -fx) == pytest.approx(a, abs=0.5 * DEG)


def test_tyre_only_dissipates_and_scales_with_friction():
    rng = np.random.default_rng(5)
    for _ in range(2000):
        fz, mu = rng.uniform(0, 9000), rng.uniform(0, 1.5)
        kappa, alpha = rng.uniform(-1.5, 2.0), rng.uniform(-1.2, 1.2)
        fx, fy = tyre_eval(fz, mu, kappa, alpha)
        assert fx * kappa >= 0 and fy * math.tan(alpha) >= 0  # force opposes the slip velocity
        assert math.hypot(fx, fy) <= mu * fz + 1e-9
    assert tyre_eval(0.0, 1.0, -0.1, 0.1) == (0.0, 0.0)
    assert tyre_eval(4000.0, 0.0, -0.1, 0.1) == (0.0, 0.0)
    lo, hi = tyre_state(4000.0, 0.3), tyre_state(4000.0, 0.9)
    assert hi.dy == pytest.approx(3 * lo.dy) and hi.dx == pytest.approx(3 * lo.dx)
    assert hi.by * hi.cy * hi.dy == pytest.approx(lo.by * lo.cy * lo.dy)  # stiffness independent of mu
    assert lo.alpha_m < hi.alpha_m  # a slippery road peaks at a smaller slip angle


def test_load_near_is_the_tangent_of_the_load_dependence():
    c = coef(FZ_SCALE)
    for fz0 in (1500.0, 5300.0, 9000.0):
        base = ffi.new("vh_mft_state_t *")
        lib.vh_mft_load(base, c, fz0, 1.0)
        h = 1e-3
        up, dn = ffi.new("vh_mft_state_t *"), ffi.new("vh_mft_state_t *")
        lib.vh_mft_load(up, c, fz0 + h, 1.0)
        lib.vh_mft_load(dn, c, fz0 - h, 1.0)
        assert base.dky == pytest.approx((up.ky - dn.ky) / (2 * h), rel=1e-6)
        assert base.dkx == pytest.approx((up.kx - dn.kx) / (2 * h), rel=1e-6)
        for dfz in (-50.0, 20.0, 200.0):
            near, exact = ffi.new("vh_mft_state_t *"), ffi.new("vh_mft_state_t *")
            lib.vh_mft_load_near(near, base, c, fz0 + dfz, 0.7)
            lib.vh_mft_load(exact, c, fz0 + dfz, 0.7)
            assert (near.dx, near.dy, near.ex, near.ey) == (exact.dx, exact.dy, exact.ex, exact.ey)
            assert near.by == pytest.approx(exact.by, rel=2e-3 * (dfz / fz0) ** 2 * 1e3 + 1e-12)
            assert near.bx == pytest.approx(exact.bx, rel=2e-3 * (dfz / fz0) ** 2 * 1e3 + 1e-12)


def test_tyre_check_rejects_unusable_coefficients():
    for field, i, bad in [("a", 0, 0.9), ("a", 0, 2.1), ("b", 2, -5.0), ("a", 8, 1.2), ("b", 4, math.nan)]:
        c = coef()
        getattr(c, field)[i] = bad
        assert lib.vh_mft_check(c) == 0, (field, i, bad)
    c = coef(0.1)
    assert lib.vh_mft_check(c) == 0
    pac = (1.3507, 1.0489, -0.0074722, -21.92, 1.6411, 1.1739, 0.46403, 22.303)  # CommonRoad's vehicle 2
    for i, bad in [(None, None), (0, 2.5), (1, 0.0), (2, 1.0), (3, 0.0), (7, -1.0), (5, math.inf)]:
        c = coef()
        c.model = lib.VH_MFT_PAC2002
        c.p[0:8] = list(pac)
        if i is not None:
            c.p[i] = bad
        assert lib.vh_mft_check(c) == (1 if i is None else 0), (i, bad)
    c.model = 7
    assert lib.vh_mft_check(c) == 0


# ---- plant: parameters and equilibrium -------------------------------------------------------

def test_defaults_are_the_papers_car():
    prm = params()
    paper = dict(ms=1661.0, ix=580.0, iz=2560.0, lf=1.076, lr=1.617, h=0.55, tf=0.784, tr=0.760, hf=0.114,
                 hr=0.004, kphi_f=108205.8, kphi_r=81436.7, cphi_f=826.8, cphi_r=658.9, rw=0.305, iw=2.0)
    for k, v in paper.items():
        assert getattr(prm, k) == v, k
    p = plant()
    assert p.m == pytest.approx(1814.0)
    assert p.e == pytest.approx(0.48, abs=1e-3)  # roll axis 0.07 m under the CG
    # the dampers give the paper's roll damping, springs + bars + tyres its roll stiffness
    assert 2 * p.c_f * prm.tf**2 == pytest.approx(prm.cphi_f)
    assert 2 * p.c_r * prm.tr**2 == pytest.approx(prm.cphi_r)
    for kphi, k, karb, t in [(prm.kphi_f, prm.k_f, p.k_arb_f, prm.tf), (prm.kphi_r, prm.k_r, p.k_arb_r, prm.tr)]:
        susp = 2 * k * t * t + karb
        assert 1 / (1 / susp + 1 / (2 * prm.kt * t * t)) == pytest.approx(kphi, rel=1e-12)
        assert karb > 0


def test_static_equilibrium_holds_at_rest_and_rolling():
    for v0 in (0.0, 25.0):
        p = plant(v0, cda=0.0)
        prm = p.prm
        l = prm.lf + prm.lr
        front = (prm.ms * prm.lr / l / 2 + prm.m_uf) * G
        rear = (prm.ms * prm.lf / l / 2 + prm.m_ur) * G
        np.testing.assert_allclose(list(p.truth.fz), [front, front, rear, rear], rtol=1e-12)
        assert sum(p.truth.fz) == pytest.approx(p.m * G, rel=1e-12)
        tr = run(p, 4000)
        for name in ("z", "phi", "theta", "vy", "r", "ay"):
            assert np.abs(tr[name]).max() < 1e-9, name
        np.testing.assert_allclose(tr["vx"], v0, atol=1e-9)
        np.testing.assert_allclose(tr["fz"], np.tile([front, front, rear, rear], (4000, 1)), rtol=1e-9)


def test_extra_mass_is_sprung_payload_at_the_cg():
    light, heavy = plant(), plant(ms=1861.0)
    assert heavy.m - light.m == pytest.approx(200.0)
    assert sum(heavy.fz0) - sum(light.fz0) == pytest.approx(200.0 * G)


# ---- plant: physics against independent references ---------------------------------------

@pytest.mark.parametrize("v_kmh, steer_deg", [(50.0, 0.5), (70.0, 0.5), (100.0, 0.3)])
def test_steady_cornering_yaw_gain_matches_the_bicycle_model(v_kmh, steer_deg):
    """Low lateral acceleration (~0.1 g): r/delta = (u/l) / (1 + K u^2 / l), K from the MF cornering stiffness."""
    p = plant(v_kmh / 3.6, cda=0.0)
    tr = run(p, 12000, steer=steer_deg * DEG)
    prm = p.prm
    l = prm.lf + prm.lr
    cf = 2 * ref_tyre(p.fz0[0], 1.0, FZ_SCALE)["ky"]
    cr = 2 * ref_tyre(p.fz0[2], 1.0, FZ_SCALE)["ky"]
    k_us = p.m / l * (prm.lr / cf - prm.lf / cr)
    u = tr["vx"][-1]
    gain_bicycle = (u / l) / (1 + k_us * u * u / l)
    assert abs(tr["ay"][-1]) < 0.15 * G
    assert np.ptp(tr["r"][-2000:]) < 1e-3 * abs(tr["r"][-1])  # steady
    assert tr["r"][-1] / (steer_deg * DEG) == pytest.approx(gain_bicycle, rel=0.01)


def test_straight_line_braking_decelerates_at_the_expected_rate():
    """m a = sum(-T_b / r_w) - 4 I_w a / r_w^2 (the wheels slow down too); pitch load transfer ms h a / l."""
    tb = 400.0
    p = plant(40.0, cda=0.0)
    tr = run(p, 16000, brake=(tb,) * 4)
    prm = p.prm
    late = slice(12000, 16000)  # after the lightly damped pitch oscillation
    a_expected = -4 * tb / (prm.rw * (p.m + 4 * prm.iw / prm.rw**2))
    assert tr["ax"][late].mean() == pytest.approx(a_expected, rel=0.005)
    v = tr["vx"][late]
    assert (v[-1] - v[0]) / (len(v) * DT) == pytest.approx(a_expected, rel=0.005)
    theta = tr["theta"][late].mean()
    assert theta > 0  # nose down
    gain = (tr["fz"][late, 0] + tr["fz"][late, 1]).mean() - (p.fz0[0] + p.fz0[1])
    l = prm.lf + prm.lr
    assert gain == pytest.approx(prm.ms * p.hp * (-tr["ax"][late].mean() + G * math.sin(theta)) / l, rel=0.01)
    assert np.abs(tr["r"]).max() < 1e-12 and np.abs(tr["vy"]).max() < 1e-12


def _roll_balance(p, ay, fy_front, fy_rear):
    """Steady roll of the documented model, solved independently: body roll phi and axle rolls."""
    prm = p.prm
    ksf = 2 * prm.k_f * prm.tf**2 + p.k_arb_f
    ksr = 2 * prm.k_r * prm.tr**2 + p.k_arb_r
    ktf, ktr = 2 * prm.kt * prm.tf**2, 2 * prm.kt * prm.tr**2
    me = prm.ms * p.e
    # unknowns phi, phi_af, phi_ar (sin phi ~ phi: phi^3/6 is below 1e-7 here)
    a = np.array([[ksf + ksr - me * G, -ksf, -ksr],
                  [-ksf, ktf + ksf, 0.0],
                  [-ksr, 0.0, ktr + ksr]])
    rhs = np.array([me * ay, fy_front * prm.hf, fy_rear * prm.hr])
    return np.linalg.solve(a, rhs)


def test_steady_cornering_roll_and_load_transfer_emerge_from_the_dynamics():
    p = plant(70 / 3.6, cda=0.0)
    tr = run(p, 12000, steer=1.5 * DEG)
    t = tr[-1]
    prm = p.prm
    phi, phi_af, phi_ar = _roll_balance(p, t["ay"], t["fyv"][0] + t["fyv"][1], t["fyv"][2] + t["fyv"][3])
    assert t["phi"] == pytest.approx(phi, rel=2e-4)
    # lateral load transfer per axle: (Fz_R - Fz_L) / 2 = kt t phi_axle
    assert (t["fz"][1] - t["fz"][0]) / 2 == pytest.approx(prm.kt * prm.tf * phi_af, rel=2e-4)
    assert (t["fz"][3] - t["fz"][2]) / 2 == pytest.approx(prm.kt * prm.tr * phi_ar, rel=2e-4)
    assert t["ay"] > 2.0 and t["phi"] > 0 and t["fz"][1] > t["fz"][0]  # left turn: leans out, right loaded
    assert sum(t["fz"]) == pytest.approx(p.m * G, rel=1e-3)


def test_roll_stiffness_is_the_papers_with_the_tyres_in_series():
    """Without roll-centre heights the body roll is ms e (a_y + g phi) / (k_phi_f + k_phi_r)."""
    p = plant(70 / 3.6, cda=0.0, hf=0.0, hr=0.0, h=0.48)
    tr = run(p, 12000, steer=1.5 * DEG)
    t = tr[-1]
    prm = p.prm
    assert p.e == pytest.approx(0.48)
    k = prm.kphi_f + prm.kphi_r
    assert t["phi"] == pytest.approx(prm.ms * 0.48 * (t["ay"] + G * math.sin(t["phi"])) / k, rel=2e-4)


def test_energy_never_appears_with_inputs_off():
    p = plant(20.0, cda=0.0)
    x = p.x
    x[lib.VH_V14_X_Z], x[lib.VH_V14_X_VZ] = 0.02, 0.1
    x[lib.VH_V14_X_PHI], x[lib.VH_V14_X_THETA] = 0.02, -0.01
    x[lib.VH_V14_X_ZU + 1] = 0.005
    x[lib.VH_V14_X_W + 2] += 2.0
    x[lib.VH_V14_X_VY], x[lib.VH_V14_X_R] = 0.3, 0.1
    inp = inputs(1)
    energy = [lib.vh_v14_energy(p)]
    for _ in range(16000):
        lib.vh_v14_step(p, inp)
        energy.append(lib.vh_v14_energy(p))
    energy = np.array(energy)
    assert np.diff(energy).max() <= 1e-9 * energy[0]
    assert energy[-1] < energy[0]
    # undisturbed and without drag, a straight-running car keeps its energy
    p = plant(20.0, cda=0.0)
    e0 = lib.vh_v14_energy(p)
    run(p, 4000)
    assert lib.vh_v14_energy(p) == pytest.approx(e0, rel=1e-12)


def _use(tr):
    return np.hypot(tr["fx"], tr["fy"]) / np.where(tr["fz"] > 0, tr["mu"] * tr["fz"], np.inf)


def test_no_tyre_force_exceeds_mu_fz():
    cases = [dict(v0=100 / 3.6, steer=6 * DEG, mu=(0.5,) * 4),                         # step steer on wet
             dict(v0=30.0, brake=(3000.0, 3000.0, 2000.0, 2000.0), mu=(1.1,) * 4),      # locking brakes
             dict(v0=5.0, drive=(1500.0, 1500.0, 0.0, 0.0), steer=10 * DEG, mu=(0.3,) * 4),  # spinning
             dict(v0=25.0, brake=(1500.0,) * 4, mu=(1.0, 0.2, 1.0, 0.2))]                # split mu
    for case in cases:
        v0 = case.pop("v0")
        tr = run(plant(v0), 8000, **case)
        assert _use(tr).max() <= 1.0 + 1e-12, case
        assert np.isfinite(tr["vx"]).all()


def test_split_mu_braking_yaws_towards_the_grippy_side():
    tr = run(plant(25.0), 2000, brake=(1500.0,) * 4, mu=(1.0, 0.2, 1.0, 0.2))
    assert tr["r"][-1] > 0.05  # left wheels (mu 1.0) brake harder: the car turns left
    assert (tr["fx"][-1, [0, 2]] < 3 * tr["fx"][-1, [1, 3]]).all()  # more (negative) force on the left


def test_relaxation_delays_the_lateral_force():
    """With relaxation the slip the tyre uses follows d(tan a_r)/dt = (|v_x| / L)(tan a - tan a_r)."""
    u, lrel = 20.0, 0.5
    quick = run(plant(u), 400, steer=1 * DEG)
    p = plant(u, relax_y=lrel)
    lag = run(p, 400, steer=1 * DEG)
    tau = int(round(lrel / u / DT))  # L / v = 25 ms
    assert quick["fy"][1, 0] > 0.5 * quick["fy"][tau, 0]  # without: at once
    assert lag["fy"][1, 0] < 0.1 * lag["fy"][2 * tau, 0]
    # the instantaneous slip of the front-left wheel from the truth's kinematics
    prm = p.prm
    vxc, vyc = lag["vx"] - lag["r"] * prm.tf, lag["vy"] + lag["r"] * prm.lf
    d = lag["steer"]
    vxw, vyw = vxc * np.cos(d) + vyc * np.sin(d), -vxc * np.sin(d) + vyc * np.cos(d)
    inst, used = -vyw / np.abs(vxw), np.tan(lag["alpha"][:, 0])
    rate = np.gradient(used, DT)[5:200]
    expect = (np.abs(vxw) / lrel * (inst - used))[5:200]
    np.testing.assert_allclose(rate, expect, rtol=0.02, atol=1e-3 * np.abs(expect).max())


def test_integration_error_against_finer_sub_steps():
    sc = load_tireforce_scenario("chassis_paper_mu_drop")
    runs = []
    for nsub in (1, 8):
        prm = sc.plant_params(ffi, lib)
        prm.min_substeps = nsub
        p = ffi.new("vh_v14_t *")
        assert lib.vh_v14_init(p, prm) == lib.VH_OK
        lib.vh_v14_set_rolling(p, sc.initial_speed_kmh / 3.6)
        out = ffi.new("vh_v14_truth_t[]", sc.n_steps)
        lib.vh_v14_run(p, sc.n_steps, sc.inputs(ffi), out)
        runs.append(truth_to_numpy(ffi, out, sc.n_steps))
    coarse, fine = runs
    assert (coarse["substeps"] == 1).all() and (fine["substeps"] == 8).all()
    assert np.abs(coarse["fy"] - fine["fy"]).max() < 2.0            # N, of up to ~2 kN
    assert np.abs(coarse["ay"] - fine["ay"]).max() < 2e-3           # m/s^2
    assert np.abs(coarse["phi"] - fine["phi"]).max() < 1e-5         # rad


def test_reset_reproduces_the_run_bit_for_bit():
    p = plant(20.0, relax_x=0.15, relax_y=0.4)
    a = run(p, 3000, steer=2 * DEG, brake=(200.0,) * 4)
    lib.vh_v14_reset(p)
    lib.vh_v14_set_rolling(p, 20.0)
    b = run(p, 3000, steer=2 * DEG, brake=(200.0,) * 4)
    for name in a.dtype.names:
        assert np.array_equal(a[name], b[name]), name
    np.testing.assert_allclose(a["t"], np.arange(3000) * DT)


def test_truth_torque_is_drive_minus_brake_and_time_is_the_step_start():
    tr = run(plant(20.0), 10, drive=(50.0, 40.0, 0.0, 0.0), brake=(0.0, 0.0, 30.0, 20.0))
    np.testing.assert_allclose(tr["torque"][-1], [50.0, 40.0, -30.0, -20.0])
    assert tr["t"][0] == 0.0 and tr["t"][-1] == pytest.approx(9 * DT)


def test_bad_inputs_are_sanitised_and_counted():
    p = plant(20.0)
    good = inputs(1)
    for field, idx, bad in [("steer", None, math.nan), ("steer", None, 2.0), ("drive", 1, math.inf),
                            ("brake", 2, -5.0), ("mu", 3, math.nan), ("mu", 0, 9.0)]:
        inp = inputs(1)
        if idx is None:
            setattr(inp[0], field, bad)
        else:
            getattr(inp[0], field)[idx] = bad
        before = p.bad_inputs
        lib.vh_v14_step(p, inp)
        assert p.bad_inputs == before + 1, field
        assert all(math.isfinite(p.x[i]) for i in range(lib.VH_V14_NX))
        assert abs(p.truth.steer) <= 0.6 and 0 <= min(p.truth.mu) and max(p.truth.mu) <= 3.0
    lib.vh_v14_step(p, good)
    assert p.bad_inputs == 6
    assert lib.vh_v14_set_rolling(p, math.nan) == lib.VH_EINVAL
    assert lib.vh_v14_set_rolling(p, 150.0) == lib.VH_EINVAL


@pytest.mark.parametrize("field, value", [
    ("ms", -1.0), ("ix", math.nan), ("kt", 0.0), ("kphi_f", 5e5),     # tyres alone softer than k_phi
    ("hf", 0.6), ("relax_y", 0.001), ("min_substeps", 0), ("min_substeps", 99), ("v_low", 0.0)])
def test_init_rejects_unphysical_parameters(field, value):
    p = ffi.new("vh_v14_t *")
    assert lib.vh_v14_init(p, params(**{field: value})) == lib.VH_EINVAL
    prm = params()
    prm.tyre.a[0] = 2.5
    assert lib.vh_v14_init(p, prm) == lib.VH_EINVAL
    assert lib.vh_v14_init(ffi.NULL, params()) == lib.VH_EINVAL


def test_init_takes_a_negative_bar_and_a_bar_residue_as_none():
    """Springs stiffer in roll than the suspension leave a negative bar (CommonRoad's auxiliary torsion
    stiffness is one): accepted while the suspension's roll stiffness is positive. A k_phi made from the
    springs alone with the tyres in series comes back as a bar of rounding size: no bar."""
    p = ffi.new("vh_v14_t *")
    assert lib.vh_v14_init(p, params(kphi_r=1e4)) == lib.VH_OK
    assert p.k_arb_r < 0 and 2 * p.prm.k_r * p.prm.tr ** 2 + p.k_arb_r > 0
    prm = params()
    ks = 2 * prm.k_r * prm.tr ** 2
    kphi = 1 / (1 / ks + 1 / (2 * prm.kt * prm.tr ** 2))
    assert 1 / (1 / kphi - 1 / (2 * prm.kt * prm.tr ** 2)) != ks  # the residue this is about
    assert lib.vh_v14_init(p, params(kphi_r=kphi)) == lib.VH_OK
    assert p.k_arb_r == 0.0


# ---- the paper's scenarios -------------------------------------------------------------------

@pytest.fixture(scope="module")
def relation_run():
    sc = load_tireforce_scenario("chassis_relation_70kph")
    return sc, sc.run_truth(ffi, lib)


@pytest.fixture(scope="module")
def mu_drop_run():
    sc = load_tireforce_scenario("chassis_paper_mu_drop")
    return sc, sc.run_truth(ffi, lib)


def test_relation_run_reproduces_relation_1(relation_run):
    """Eq. 31-32: F_yf / phi and F_yr / phi nearly constant below 0.5 g (paper's Fig. 3)."""
    sc, tr = relation_run
    assert tr["steer"][-1] == pytest.approx(4 * DEG, rel=1e-3) and tr["vx"][0] == pytest.approx(70 / 3.6)
    ayg = tr["ay"] / G
    band = (ayg > 0.1) & (ayg < 0.5)
    assert band.sum() > 6000
    for fy in ("fyf", "fyr"):
        zeta = tr[fy][band] / tr["phi"][band]
        assert np.ptp(zeta) < 0.06 * zeta.mean(), fy  # measured 3.2 % front, 4.6 % rear
    assert _use(tr).max() <= 1.0


def test_relation_run_relation_2_direction(relation_run):
    """Eq. 33-34: the outer tyres carry more than the axle mean, the inner ones less, as their loads
    do; with this tyre's load sensitivity the force ratio moves 49-66 % (front) and 65-80 % (rear)
    as far as the load ratio."""
    sc, tr = relation_run
    p = sc.make_plant(ffi, lib)
    ayg = tr["ay"] / G
    band = (ayg > 0.2) & (ayg < 0.5)
    band = (ayg > 0.1) & (ayg < 0.5)
    for w, axle, lo, hi in [(0, "fyf", 0.45, 0.7), (1, "fyf", 0.45, 0.7), (2, "fyr", 0.6, 0.85), (3, "fyr", 0.6, 0.85)]:
        fy_ratio = tr["fy"][band, w] / tr[axle][band] - 1
        fz_ratio = tr["fz"][band, w] / p.fz0[w] - 1
        share = fy_ratio / fz_ratio
        assert (share > lo).all() and (share < hi).all(), w
        assert (np.sign(fy_ratio) == np.sign(fz_ratio)).all()


def test_paper_mu_drop_run(mu_drop_run):
    sc, tr = mu_drop_run
    assert sc.mass_delta_kg == 200.0
    t = tr["t"]
    before = (t > 5.0) & (t < 6.0)
    after = t > 7.0
    assert 2.5 < tr["ay"][before].mean() < 4.0                      # ~0.35 g on the dry road at 2 deg
    m = 1814.0 + 200.0
    assert np.abs(tr["fyv"][after].sum(axis=1)).max() < 0.2 * G * m   # mu 0.2 caps the lateral force
    assert np.abs(tr["ay"][after]).mean() < 0.2 * G
    assert tr["fyf"][after].mean() < 0.6 * tr["fyf"][before].mean()
    np.testing.assert_allclose(tr["torque"][t > 1.2], np.tile([-60.0, -60.0, -40.0, -40.0], ((t > 1.2).sum(), 1)))
    assert _use(tr).max() <= 1.0 + 1e-12
    assert sum(tr["fz"][0]) == pytest.approx((1814.0 + 200.0) * G, rel=1e-9)


# ---- chassis sensor node -----------------------------------------------------------------------

@pytest.fixture(scope="module")
def ch_db():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return cantools.database.load_file(str(ROOT / "dbc" / "vehest_ch.dbc"), strict=True)


CHANNELS = [("LongAccel", "ax", None, 0.001), ("LatAccel", "ay", None, 0.001), ("YawRate", "r", None, 1e-4),
            ("RollRate", "p", None, 1e-4), ("SteerAngle", "steer", None, 1e-4)] + \
           [(f"WheelSpeed{w}", "omega", i, 0.01) for i, w in enumerate(("FL", "FR", "RL", "RR"))] + \
           [(f"WheelTorque{w}", "torque", i, 0.25) for i, w in enumerate(("FL", "FR", "RL", "RR"))]


def node(**over):
    cfg = ffi.new("vh_chs_config_t *")
    lib.vh_chs_config_default(cfg)
    for k, v in over.items():
        if k in ("noise_std", "bias"):
            for i, s in enumerate(v):
                getattr(cfg, k)[i] = s
        else:
            setattr(cfg, k, v)
    n = ffi.new("vh_chs_t *")
    assert lib.vh_chs_init(n, cfg) == lib.VH_OK
    return n


def node_frame(n, truth):
    out = ffi.new("vh_frame_t[2]")
    assert lib.vh_chs_step(n, truth, out, 2) == 1
    return out[0], bytes(out[0].data[0:out[0].len])


def phys(truth, field, i):
    v = getattr(truth, field)
    return v[i] if i is not None else v


def drive_plant(p, k):
    inp = inputs(1, steer=2 * DEG * min(k / 200, 1), drive=(80.0, 80.0, 0.0, 0.0), brake=(0.0, 0.0, 30.0, 30.0))
    lib.vh_v14_step(p, inp)


def test_node_frame_without_noise_is_truth_quantised(ch_db):
    n = node(noise_std=[0.0] * 13)
    p = plant(20.0)
    msg = ch_db.get_message_by_name("CHS_Sensors")
    for k in range(400):
        drive_plant(p, k)
        f, data = node_frame(n, ffi.addressof(p, "truth"))
        assert f.id == msg.frame_id == 0x110 and not msg.is_extended_frame
        assert f.len == 32 and f.flags == lib.VH_FRAME_FD | lib.VH_FRAME_BRS
        assert all(b == 0 for b in f.data[32:64])
        sig = ch_db.decode_message(msg.frame_id, data, decode_choices=False)
        for name, field, i, scale in CHANNELS:
            v = phys(p.truth, field, i)
            assert sig[name] == pytest.approx(round(v / scale) * scale, abs=1e-9), name
            assert sig[f"Qf_{name}"] == 1
    assert p.truth.ay > 1.0 and p.truth.r > 0.05  # the frames carried a real manoeuvre


def test_node_noise_and_bias_match_the_configuration(ch_db):
    std = [0.05, 0.05, 0.005, 0.005, 0.0005, 0.1, 0.1, 0.1, 0.1, 2.0, 2.0, 2.0, 2.0]
    bias = [0.1, -0.2, 0.01, 0.0, 0.001, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0, -3.0, 0.0]
    n = node(noise_std=std, bias=bias, seed=99)
    p = plant(20.0)
    msg = ch_db.get_message_by_name("CHS_Sensors")
    err = []
    for k in range(12000):
        drive_plant(p, k)
        _, data = node_frame(n, ffi.addressof(p, "truth"))
        sig = msg.decode(data, decode_choices=False)
        err.append([sig[name] - phys(p.truth, field, i) for name, field, i, _ in CHANNELS])
    err = np.array(err)
    quant = np.array([s for *_, s in CHANNELS]) ** 2 / 12
    np.testing.assert_allclose(err.std(axis=0), np.sqrt(np.array(std) ** 2 + quant), rtol=0.05)
    assert np.all(np.abs(err.mean(axis=0) - bias) < 5 * np.sqrt(np.array(std) ** 2 + quant) / math.sqrt(len(err)))
    assert np.abs(np.corrcoef(err.T)[np.triu_indices(13, 1)]).max() < 0.06  # channels independent


def test_node_e2e_crc_and_counter(ch_db):
    msg = ch_db.get_message_by_name("CHS_Sensors")
    data_id, length = msg.dbc.attributes["E2EDataID"].value, msg.length
    n, p = node(), plant(10.0)
    rx = ffi.new("vh_e2e_rx_t *")
    lib.vh_e2e_rx_init(rx)
    counters = []
    for k in range(40):
        drive_plant(p, k)
        f, data = node_frame(n, ffi.addressof(p, "truth"))
        assert e2e.p01.e2e_p01_check(bytearray(bytes(data)[:length]), data_id)  # AUTOSAR's P01, independently
        counters.append(data[1] & 0x0F)
        assert lib.vh_e2e_check(lib.vh_ch_e2e_cfg(msg.frame_id), rx, f.data, length) == (
            lib.VH_E2E_INITIAL if k == 0 else lib.VH_E2E_OK)
    assert counters == [k % 15 for k in range(40)] and n.frames == 40


def test_node_clamps_flags_failures_and_feels_gravity_when_asked(ch_db):
    msg = ch_db.get_message_by_name("CHS_Sensors")
    n = node(noise_std=[0.0] * 13)
    t = ffi.new("vh_v14_truth_t *")
    t.ax, t.ay, t.r = 100.0, math.nan, -10.0
    t.omega = [-3.0, 1e5, 50.0, 50.0]
    _, data = node_frame(n, t)
    raw = msg.decode(data, decode_choices=False, scaling=False)
    # (15-bit accelerations, yaw rate and wheel speeds: CHS_Sensors packed for its SecOC tail)
    assert raw["LongAccel"] == 16383 and raw["Qf_LongAccel"] == 1           # clamped, -16384 is SNA
    assert raw["LatAccel"] == -16384 and raw["Qf_LatAccel"] == 0             # NaN: SNA, INVALID
    assert raw["YawRate"] == -16383
    assert raw["WheelSpeedFL"] == 0 and raw["WheelSpeedFR"] == 32766         # 32767 is SNA
    n.cfg.fail_mask = 1 << (lib.VH_CHS_CH_W + 2)
    _, data = node_frame(n, t)
    raw = msg.decode(data, decode_choices=False, scaling=False)
    assert raw["WheelSpeedRL"] == 32767 and raw["Qf_WheelSpeedRL"] == 0
    assert ch_db.decode_message(msg.frame_id, data)["Qf_WheelSpeedRL"] == "INVALID"
    # gravity through body roll and pitch: a_y + g sin(phi), a_x - g sin(theta)
    g = node(noise_std=[0.0] * 13, accel_gravity=1)
    t2 = ffi.new("vh_v14_truth_t *")
    t2.ax, t2.ay, t2.phi, t2.theta = -1.0, 3.0, 0.02, 0.01
    sig = msg.decode(node_frame(g, t2)[1], decode_choices=False)
    assert sig["LatAccel"] == pytest.approx(3.0 * math.cos(0.02) + G * math.sin(0.02), abs=6e-4)
    assert sig["LongAccel"] == pytest.approx(-1.0 * math.cos(0.01) - G * math.sin(0.01), abs=6e-4)


def test_node_rejects_bad_config_and_small_buffers():
    cfg = ffi.new("vh_chs_config_t *")
    for field, bad in [("noise_std", -1.0), ("noise_std", math.nan), ("bias", math.inf)]:
        lib.vh_chs_config_default(cfg)
        getattr(cfg, field)[3] = bad
        assert lib.vh_chs_init(ffi.new("vh_chs_t *"), cfg) == lib.VH_EINVAL
    n, p = node(), plant()
    out = ffi.new("vh_frame_t[1]")
    assert lib.vh_chs_step(n, ffi.addressof(p, "truth"), out, 0) == 0
    assert lib.vh_chs_step(n, ffi.NULL, out, 1) == 0
    assert n.frames == 0 and n.counter == 0


# ---- chassis DBC -------------------------------------------------------------------------------

def test_ch_dbc_loads_strict_with_e2e_and_cycle_attributes(ch_db):
    assert {m.name for m in ch_db.messages} >= {"CHS_Sensors", "VEHEST_TireForceEst", "VEHEST_ChassisStatus",
                                                 "VEHEST_TireForceAdaptive"}
    assert {nd.name for nd in ch_db.nodes} >= {"CHS", "VEHEST"}  # and the roll system's (docs/roll.md)
    pt = cantools.database.load_file(str(ROOT / "dbc" / "vehest_pt.dbc"))
    pt_ids = {m.frame_id for m in pt.messages}
    pt_data_ids = {m.dbc.attributes["E2EDataID"].value for m in pt.messages if "E2EDataID" in m.dbc.attributes}
    for m in ch_db.messages:
        a = m.dbc.attributes
        assert m.is_fd and m.senders and m.comment, m.name
        if "SecOCSync" in a:  # a SecOC freshness sync frame: its MAC is its protection, no E2E (docs/secoc.md)
            assert a["SecOCDataID"].value > 0 and [s.name for s in m.signals][-1] == "SecOCSyncMAC", m.name
            continue
        assert a["E2EProfile"].value == "P01" and a["E2EDataID"].value == 0x1000 + m.frame_id
        assert a["CycleTimeUs"].value > 0
        assert m.frame_id not in pt_ids and a["E2EDataID"].value not in pt_data_ids
        crc, counter = m.signals[0], m.signals[1]
        assert (crc.start, crc.length, counter.start, counter.length) == (0, 8, 8, 4)
        for s in m.signals:
            assert s.comment, (m.name, s.name)
    est = ch_db.get_message_by_name("VEHEST_TireForceEst")
    names = {s.name for s in est.signals}
    assert {"Fy1", "Fy2", "Fy3", "Fy4", "Fyf", "Fyr", "EstVx", "EstVy", "EstYawRate", "EstRollAngle"} <= names
    assert {"SkfmecQ_Health", "SkfmecQ_Valid"} <= names
    assert est.get_signal_by_name("Fy1").unit == "N" and est.senders == ["VEHEST"]
    sens = ch_db.get_message_by_name("CHS_Sensors")
    assert sens.dbc.attributes["CycleTimeUs"].value == 500 and sens.senders == ["CHS"]


@pytest.mark.parametrize("name", ["CHS_Sensors", "VEHEST_TireForceEst", "VEHEST_ChassisStatus",
                                  "VEHEST_TireForceAdaptive"])
@settings(max_examples=100, deadline=None)
@given(data=st.data())
def test_ch_codec_equals_cantools(ch_db, name, data):
    m = ch_db.get_message_by_name(name)
    values = {}
    for s in m.signals:
        lo, hi = ((-(1 << (s.length - 1)), (1 << (s.length - 1)) - 1) if s.is_signed else (0, (1 << s.length) - 1))
        values[s.name] = data.draw(st.integers(lo, hi))
    base = f"vh_ch_{camel_to_snake_case(m.name)}"
    src = ffi.new(f"struct {base}_t *")
    for s in m.signals:
        setattr(src, camel_to_snake_case(s.name), values[s.name])
    dst = ffi.new("uint8_t[]", m.length)
    assert getattr(lib, f"{base}_pack")(dst, src, m.length) == m.length
    assert bytes(ffi.buffer(dst, m.length)) == m.encode(values, scaling=False, strict=False, padding=False)


def test_ch_bus_load_within_budget(capsys, tmp_path):
    load = bus_load(ROOT / "dbc" / "vehest_ch.dbc")
    assert (load.bitrate, load.data_bitrate) == (500_000, 4_000_000)
    assert load.worst_pct <= 60.0
    # 45.87 % + roll at 5 ms + SKFMEC-A at 10 ms + the SecOC tails and sync frames, the tyre-force
    # estimates secured at 2 ms (docs/secoc.md), the ride heights at 10 ms (+1.04 points), the chassis
    # sensor frames secured (CHS_Sensors packed to keep 32 bytes, CHS_RideHeight 16, a sync frame: +0.11),
    # SKFMEC-A's frame 24 bytes with the tyre bounds (+0.10)
    assert load.worst_pct == pytest.approx(54.27, abs=0.01)
    assert cli_main(["busload", str(ROOT / "dbc" / "vehest_ch.dbc")]) == 0
    sys.path.insert(0, str(ROOT / "c_core"))
    import dbcgen

    dbcgen.generate_all(tmp_path)
    meta = (tmp_path / "vh_ch_meta.h").read_text()
    assert "VH_CH_CHS_SENSORS_CYCLE_TIME_US (500u)" in meta
    assert "VH_CH_VEHEST_TIRE_FORCE_EST_CYCLE_TIME_US (2000u)" in meta
    assert "VH_CH_CHS_SENSORS_E2E_DATA_ID (4368u)" in meta


# ---- chassis scenarios -------------------------------------------------------------------------

GOOD = """\
kind = "tireforce"
name = "mine"
duration_s = 1.0

[driver]
steer_deg = [[0.0, 0.0], [0.5, 1.0]]
"""


def write(tmp_path, text, name="c.toml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def test_shipped_chassis_scenarios_load_and_follow_the_paper():
    assert set(list_tireforce_scenarios()) == {"chassis_relation_70kph", "chassis_paper_mu_drop"}
    assert tireforce_scenario_dir().name == "tireforce"
    rel = load_tireforce_scenario("chassis_relation_70kph")
    assert rel.initial_speed_kmh == 70.0 and rel.duration_s == 10.0
    np.testing.assert_allclose(rel.steer_rad_at([0.0, 5.0, 10.0]), np.radians([0.0, 2.0, 4.0]))
    drop = load_tireforce_scenario("chassis_paper_mu_drop")
    t = np.array([0.0, 2.0, 5.0, 9.0])
    np.testing.assert_allclose(np.degrees(drop.steer_rad_at(t)), [0.0, 1.0, 2.0, 2.0])
    np.testing.assert_allclose(drop.brake_at([5.0])[0], [60.0, 60.0, 40.0, 40.0])
    np.testing.assert_allclose(drop.mu_at([0.0, 9.0]), [[1.1] * 4, [0.2] * 4])
    assert drop.mass_delta_kg == 200.0
    prm = drop.plant_params(ffi, lib)
    assert prm.ms == 1661.0 + 200.0
    # the driveline side does not see them
    assert not set(list_driveline_scenarios()) & set(list_tireforce_scenarios())
    assert not list(driveline_scenario_dir().glob("chassis_*.toml"))


def test_good_file_defaults_and_input_layout(tmp_path):
    sc = load_tireforce_scenario(write(tmp_path, GOOD))
    assert (sc.name, sc.seed, sc.initial_speed_kmh, sc.mass_delta_kg, sc.accel_gravity) == ("mine", 1, 0.0, 0.0, False)
    arr = sc.input_array()
    assert arr.shape == (2000, 13)
    np.testing.assert_allclose(arr[:, 0], np.radians(np.interp(np.arange(2000) * DT, [0, 0.5], [0, 1])))
    assert (arr[:, 1:9] == 0).all() and (arr[:, 9:] == 1.0).all()
    cin = sc.inputs(ffi)
    assert cin[1000].steer == arr[1000, 0] and list(cin[5].mu) == [1.0] * 4


def test_split_mu_sensors_tyre_and_vehicle_keys(tmp_path):
    sc = load_tireforce_scenario(write(tmp_path, GOOD + """
        [road]
        mu_left = [[0.0, 1.0]]
        mu_right = [[0.0, 0.3], [0.5, 0.2]]
        [vehicle]
        mass_delta_kg = 150.0
        roll_inertia_kgm2 = 600.0
        [tyre]
        relaxation_length_y_m = 0.4
        [sensors]
        ay_std_m_s2 = 0.1
        yaw_rate_bias_rad_s = 0.002
        wheel_torque_std_nm = 5.0
        accel_gravity = true
        """))
    np.testing.assert_allclose(sc.mu_at([1.0])[0], [1.0, 0.2, 1.0, 0.2])
    prm = sc.plant_params(ffi, lib)
    assert (prm.ms, prm.ix, prm.relax_y) == (1661.0 + 150.0, 600.0, 0.4)
    cfg = sc.node_config(ffi, lib)
    assert cfg.noise_std[1] == 0.1 and cfg.bias[2] == 0.002 and list(cfg.noise_std)[9:13] == [5.0] * 4
    assert cfg.accel_gravity == 1 and cfg.seed == sc.node_seed and cfg.ride_period == 20
    tr, frames = sc.run_with_frames(ffi, lib)
    chs = [pl for i, pl in frames if i == 0x110]
    ride = [pl for i, pl in frames if i == 0x111]
    assert len(chs) == len(tr) == 2000 and all(len(pl) == 32 for pl in chs)
    assert len(ride) == 100 and all(len(pl) == 16 for pl in ride) and len(frames) == 2100


@pytest.mark.parametrize("text, key, fragment", [
    ('name = "x"\nduration_s = 1.0\n[driver]\nsteer_deg = [[0.0, 0.0]]\n', "kind", 'kind = "tireforce"'),
    ('kind = "driveline"\nname = "x"\nduration_s = 1.0\n', "kind", 'must be "tireforce"'),
    ("speed = 3\n" + GOOD, "speed", "unknown key"),
    (GOOD.replace("duration_s = 1.0", ""), "duration_s", "missing"),
    (GOOD.replace("steer_deg", "steer"), "driver.steer", "unknown key"),
    (GOOD + "[road]\nmu = [[0.0, 1.0]]\nmu_left = [[0.0, 1.0]]\n", "road.mu_left", "not both"),
    (GOOD + "[road]\nmu_left = [[0.0, 1.0]]\n", "road.mu_right", "needs both"),
    (GOOD + "[road]\nmu = [[0.0, 3.0]]\n", "road.mu[0][1]", "out of range"),
    (GOOD.replace("[0.5, 1.0]", "[0.0, 1.0]"), "driver.steer_deg[1]", "increase strictly"),
    (GOOD + "brake_nm = [[0.0, 1.0, 2.0, 3.0]]\n", "driver.brake_nm[0]", "5 values"),
    (GOOD + "brake_nm = [[0.0, 1.0, 2.0, 3.0, -4.0]]\n", "driver.brake_nm[0][4]", "out of range"),
    (GOOD + "drive_nm = [[0.0, 1.0, 2.0, true, 4.0]]\n", "driver.drive_nm[0][3]", "not a boolean"),
    (GOOD + "[vehicle]\nmass_delta_kg = 5000.0\n", "vehicle.mass_delta_kg", "out of range"),
    (GOOD + "[vehicle]\nroll_stiffness_front_nm_per_rad = 900000.0\n", "vehicle", "refuses"),
    (GOOD + "[tyre]\nlateral_coefficients = [2.5, -22.1, 1011, 1078, 1.82, 0.208, 0, -0.354, 0.707]\n",
     "tyre", "peaked curve"),
    (GOOD + "[tyre]\nlateral_coefficients = [1.3]\n", "tyre.lateral_coefficients", "9"),
    ('car = "commonroad_vehicle2"\n' + GOOD
     + "[tyre]\nlateral_coefficients = [1.3, -22.1, 1011, 1078, 1.82, 0.208, 0, -0.354, 0.707]\n", "tyre", "PAC2002"),
    (GOOD + "[sensors]\naccel_gravity = 1\n", "sensors.accel_gravity", "true or false"),
    (GOOD + "[sensors]\nay_std_m_s2 = -1.0\n", "sensors.ay_std_m_s2", "out of range"),
    ("kind = \"tireforce\"\nname = \"x\"\nduration_s = [1\n", "(TOML syntax)", ""),
])
def test_chassis_loader_errors_name_file_and_key(tmp_path, text, key, fragment):
    path = write(tmp_path, text)
    with pytest.raises(ScenarioError) as exc:
        load_tireforce_scenario(path)
    msg = str(exc.value)
    assert msg.startswith(f"{path}: {key}"), msg
    assert fragment in msg


def test_loaders_keep_to_their_own_files(tmp_path):
    with pytest.raises(ScenarioError, match='kind: must be "driveline", not \'tireforce\''):
        load_driveline_scenario(tireforce_scenario_dir() / "chassis_paper_mu_drop.toml")
    with pytest.raises(ScenarioError, match='kind: must be "tireforce", not \'driveline\''):
        load_tireforce_scenario(driveline_scenario_dir() / "launch_2nd.toml")
    with pytest.raises(ScenarioError, match="cannot read"):
        load_tireforce_scenario(tmp_path / "nope.toml")
    assert isinstance(load_tireforce_scenario("chassis_paper_mu_drop"), Veh14Scenario)


def test_plant_bench():
    from vehest_can.sim.veh14 import bench
    figures = bench(load_tireforce_scenario("chassis_paper_mu_drop"), seconds=1.0, repeats=1)
    assert figures["steps"] == 2000 and figures["x_real_time_cpu_best"] > 1.0


# ---- sanitizers --------------------------------------------------------------------------------

@pytest.mark.rebuild
@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_plant_tyre_and_node_under_asan_ubsan(tmp_path):
    sys.path.insert(0, str(ROOT / "c_core"))
    import vehest_build

    gen = tmp_path / "generated"
    sources = [str(s) for s in vehest_build.firmware_sources(gen)] + [str(ROOT / "tests" / "c" / "sanitize_veh14.c")]
    inc = [f"-I{d}" for d in vehest_build.sim_include_dirs(gen)]
    exe = tmp_path / "san"
    san = ["-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer", "-g", "-O1"]
    build = subprocess.run(["cc", *vehest_build.STRICT_FLAGS, *san, *inc, *sources, *vehest_build.LINK_FLAGS, "-o", str(exe)],
                           capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    res = subprocess.run([str(exe)], capture_output=True, text=True, timeout=600,
                         env={"ASAN_OPTIONS": "detect_leaks=1", "UBSAN_OPTIONS": "print_stacktrace=1"})
    assert res.returncode == 0, res.stdout + res.stderr
    assert "sanitize_veh14: ok" in res.stdout and "runtime error" not in res.stderr
