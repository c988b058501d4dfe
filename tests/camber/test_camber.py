"""Camber inspection (seed 002): C core vs the numpy reference vs the simulated truth.

The C firmware runs in float32, so C-vs-reference comparisons use float32 tolerances; the
reference itself (float64) is held against scipy's numerical solution and finite differences.
"""
from __future__ import annotations

import json
import math
import re
import shutil
import subprocess
import sysconfig
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import minimize, root

from vehest_can.errors import ConfigError
from vehest_can.native import ffi, lib
from vehest_can.systems.camber import api as camber
from vehest_can.systems.camber import reference as ref
from vehest_can.systems.camber.api import (
    Calibration,
    CalibrationLimits,
    CamberNode,
    CaptureError,
    MeasureConfig,
    Reason,
    calibrate,
    measure,
    measure_windows,
)

ROOT = Path(__file__).resolve().parents[2]
LSB = 0.004  # 4 mg
CHIP = tuple(np.radians([2.0, -1.5, 2.5]))  # chip rotation inside the device (~2-3 deg)
DEG = math.pi / 180


def f3(v):
    return ffi.new("float[3]", [float(x) for x in v])


def c_angles(a):
    th, ps = ffi.new("float *"), ffi.new("float *")
    lib.vh_camber_angles(f3(a), th, ps)
    return th[0], ps[0]


@pytest.fixture(scope="module")
def calibrated():
    """A device with a ~2.5 deg chip misalignment, calibrated on the fixture (2 x 2048 samples)."""
    node = CamberNode(chip=CHIP, noise_std_g=LSB, seed=11)
    cal = calibrate(node.capture(2048, "x_down"), node.capture(2048, "z_down"))
    return node, cal


# ---- Frames and angles (eq. 1-6) ---------------------------------------------------------

def test_digest_v_s_matrix_is_the_product_of_eq1_and_eq2():
    rng = np.random.default_rng(0)
    for th, ps in rng.uniform(-1.5, 1.5, size=(50, 2)):
        r = ref.rot_v_w(th) @ ref.rot_w_s(ps)
        np.testing.assert_allclose(ref.rot_v_s_printed(th, ps), r, atol=1e-15)
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
        # gravity (0, 0, g)_V seen in S, mapped back to V by eq. 3
        np.testing.assert_allclose(r @ ref.gravity_s(th, ps, 9.81), [0, 0, 9.81], atol=1e-14)


def test_reference_eq4_to_6_recover_the_angles():
    th, ps = np.meshgrid(np.radians(np.linspace(-10, 10, 21)), np.radians(np.linspace(-60, 60, 25)))
    a = ref.gravity_s(th, ps, 0.98)
    np.testing.assert_allclose(ref.psi_eq4(a), ps, atol=1e-14)
    np.testing.assert_allclose(ref.theta_eq6(a), th, atol=1e-14)
    np.testing.assert_allclose(ref.theta_eq5(a), ref.theta_eq6(a), atol=1e-14)


def test_c_angles_match_reference():
    rng = np.random.default_rng(1)
    for _ in range(200):
        th, ps = rng.uniform(-0.5, 0.5), rng.uniform(-1.4, 1.4)
        a = np.asarray(ref.gravity_s(th, ps, rng.uniform(0.9, 1.1))) + rng.normal(scale=0.01, size=3)
        cth, cps = c_angles(a)
        assert abs(cth - ref.theta_eq6(a)) < 2e-6
        assert abs(cps - ref.psi_eq4(a)) < 2e-6


def test_theta_does_not_depend_on_psi():
    """eq. 6: sweep psi at fixed theta. Exact inputs through the C; then simulated data."""
    th = 1.5 * DEG
    psis = np.radians(np.linspace(-10, 10, 21))
    exact = [c_angles(ref.gravity_s(th, p))[0] for p in psis]
    assert np.ptp(exact) < 1e-6 and abs(np.mean(exact) - th) < 1e-6
    node = CamberNode(theta=th, chip=CHIP, noise_std_g=LSB, seed=5)
    cal = calibrate(node.capture(2048, "x_down"), node.capture(2048, "z_down"))
    cal_th, unc_th = [], []
    for p in psis:
        node.set_wheel(th, p)
        w = node.capture(256)
        r = measure(w, cal)
        assert r.ok and abs(r.theta - th) <= r.bound and abs(r.psi - p) < 0.01
        cal_th.append(r.theta)
        unc_th.append(measure(w, Calibration.identity()).theta)
    # theta's trend over the 20 deg psi sweep (linear fit): noise alone is ~0.014 deg per window
    cal_trend = np.polyfit(psis, cal_th, 1)[0] * np.ptp(psis)
    unc_trend = np.polyfit(psis, unc_th, 1)[0] * np.ptp(psis)
    print(f"\ntheta over psi sweep (-10..10 deg): calibrated trend {math.degrees(cal_trend):+.4f} deg, spread "
          f"{math.degrees(np.ptp(cal_th)):.4f} deg; uncalibrated trend {math.degrees(unc_trend):+.4f} deg")
    # With the chip misaligned and no calibration, psi leaks into theta; calibrated it does not.
    assert abs(cal_trend) < 0.03 * DEG
    assert abs(unc_trend) > 0.5 * DEG


# ---- Error analysis (eq. 20-23) ----------------------------------------------------------

def test_paper_minimum_error_0_2292_deg_computed():
    """eq. 22 at theta = 0 with 4 mg on every axis (g = 1 g) against the paper's printed 0.2292 deg."""
    da = [LSB, LSB, LSB]
    ref_deg = math.degrees(ref.worst_case_error(0.0, 0.0, da, 1.0))
    c_deg = math.degrees(lib.vh_camber_bound(0.0, 0.0, da, 1.0))
    print(f"\neq. 22 at theta = 0, 4 mg: reference {ref_deg:.5f} deg, C {c_deg:.5f} deg, paper 0.2292 deg")
    assert abs(ref_deg - 0.2292) < 5e-4
    assert abs(c_deg - 0.2292) < 5e-4
    # eq. 23: it is the minimum of eq. 22 over the (theta, psi) map of Fig. 5
    th, ps = np.meshgrid(np.radians(np.linspace(-10, 10, 41)), np.radians(np.linspace(-30, 30, 61)))
    grid = ref.worst_case_error(th, ps, np.array(da), 1.0)
    assert grid.min() == pytest.approx(ref.min_error_eq23(LSB), rel=1e-12)
    assert ref.worst_case_error(0.0, 0.3, da) == pytest.approx(ref.min_error_eq23(LSB), rel=1e-12)


def test_c_bound_matches_reference_eq22():
    rng = np.random.default_rng(2)
    for _ in range(200):
        th, ps = rng.uniform(-0.3, 0.3), rng.uniform(-1.0, 1.0)
        da = rng.uniform(0.001, 0.01, size=3)
        g = rng.uniform(0.95, 1.05)
        assert lib.vh_camber_bound(th, ps, f3(da), g) == pytest.approx(ref.worst_case_error(th, ps, da, g), rel=1e-5)


def test_eq20_gradient_and_the_printed_ax_sign():
    """Finite differences of eq. 6 against the gradient: eq. 20 as printed has the ax term's sign
    flipped for the eq. 3-4 conventions; magnitudes (all eq. 22 uses) agree."""
    h = 1e-6
    for th, ps in [(0.05, 0.2), (-0.04, 0.15), (0.03, -0.17)]:
        a = ref.gravity_s(th, ps)
        fd = np.array([(ref.theta_eq6(a + h * e) - ref.theta_eq6(a - h * e)) / (2 * h) for e in np.eye(3)])
        np.testing.assert_allclose(fd, ref.theta_gradient(th, ps), atol=1e-9)
        printed = np.array([ref.dtheta_eq21(th, ps, e) for e in np.eye(3)])
        np.testing.assert_allclose(np.abs(printed), np.abs(fd), atol=1e-9)
        np.testing.assert_allclose(printed[1:], fd[1:], atol=1e-9)
        assert np.sign(printed[0]) == -np.sign(fd[0])


# ---- Calibration (eq. 7-19) -------------------------------------------------------------

def _random_capture(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 300))
    d = ref.unit(rng.normal(size=3))
    return d * rng.uniform(0.5, 2.0) + rng.normal(scale=rng.uniform(0.001, 0.3), size=(n, 3))


@pytest.mark.parametrize("seed", range(25))
def test_closed_form_equals_numerical_constrained_solution(seed):
    """eq. 14-16 against SLSQP on eq. 7-8 (from a generic start) and a root solve of eq. 9's
    stationarity conditions, to 1e-9; eq. 13's lambda against the solved multiplier."""
    s = _random_capture(seed)
    n = len(s)
    radius = np.mean(np.linalg.norm(s, axis=1))
    closed = ref.constrained_mean(s)
    res = minimize(lambda m: ref.objective_eq7(m, s) / n, s[0], jac=lambda m: 2 * np.sum(m - s, axis=0) / n,
                   method="SLSQP", options={"ftol": 1e-15, "maxiter": 500},
                   constraints=[{"type": "eq", "fun": lambda m: ref.constraint_eq8(m, s), "jac": lambda m: 2 * m}])
    assert res.success
    assert np.max(np.abs(res.x - closed)) < 1e-9

    def kkt(v):  # dL/dmean = 0 (eq. 10-12 before solving), dL/dlambda = 0 (eq. 8)
        m, lam = v[:3], v[3]
        return np.r_[2 * np.sum(m - s, axis=0) + 2 * lam * m, m @ m - radius ** 2]

    sol = root(kkt, np.r_[s.mean(axis=0), 0.0], tol=1e-15)  # may stop on "xtol too small": check residual
    assert np.max(np.abs(kkt(sol.x))) < 1e-10
    assert np.max(np.abs(sol.x[:3] - closed)) < 1e-9
    assert sol.x[3] == pytest.approx(ref.lagrange_multiplier_eq13(s), rel=1e-9, abs=1e-9)
    np.testing.assert_allclose(ref.constrained_mean_eq10_12(s), closed, atol=1e-12)


def test_closed_form_vs_numerical_max_diff_report():
    worst_slsqp = worst_root = 0.0
    for seed in range(25):
        s = _random_capture(seed)
        n = len(s)
        closed = ref.constrained_mean(s)
        res = minimize(lambda m: ref.objective_eq7(m, s) / n, s[0], jac=lambda m: 2 * np.sum(m - s, axis=0) / n,
                       method="SLSQP", options={"ftol": 1e-15, "maxiter": 500},
                       constraints=[{"type": "eq", "fun": lambda m: ref.constraint_eq8(m, s), "jac": lambda m: 2 * m}])
        r2 = float(np.mean(np.linalg.norm(s, axis=1))) ** 2
        sol = root(lambda v: np.r_[2 * np.sum(v[:3] - s, axis=0) + 2 * v[3] * v[:3], v[:3] @ v[:3] - r2],
                   np.r_[s.mean(axis=0), 0.0], tol=1e-15)
        worst_slsqp = max(worst_slsqp, float(np.max(np.abs(res.x - closed))))
        worst_root = max(worst_root, float(np.max(np.abs(sol.x[:3] - closed))))
    print(f"\nclosed form (eq. 14-16) vs numerical, 25 random captures: max |diff| SLSQP {worst_slsqp:.3e}, "
          f"Lagrange root solve {worst_root:.3e}")
    assert worst_slsqp < 1e-9 and worst_root < 1e-9


def test_c_capture_mean_matches_reference():
    rng = np.random.default_rng(3)
    for n in (10, 1000, int(lib.VH_CAMBER_N_MAX)):  # the longest capture exercises the Kahan sum
        d = ref.unit([0.05, -0.03, 1.0])
        raw = np.round((d + rng.normal(scale=0.01, size=(n, 3))) / LSB).astype(np.int16)
        cap = ffi.new("vh_camber_capture_t *")
        assert lib.vh_camber_capture_init(cap, f3([LSB] * 3)) == lib.VH_OK
        assert lib.vh_camber_capture_add_n(cap, n, ffi.from_buffer("int16_t[]", raw)) == lib.VH_OK
        out = ffi.new("float[3]")
        assert lib.vh_camber_capture_mean(cap, out) == lib.VH_OK
        expect = ref.constrained_mean(raw * np.float32(LSB).astype(float))
        np.testing.assert_allclose(list(out), expect, rtol=2e-6, atol=2e-7)
    # full: one more sample is refused
    assert lib.vh_camber_capture_add(cap, ffi.new("int16_t[3]", [0, 0, 250])) == lib.VH_ENOSPC


def test_c_calibration_matches_reference_and_truth(calibrated):
    node, cal = calibrated
    xd, zd = node.capture(1024, "x_down"), node.capture(1024, "z_down")
    c = calibrate(xd, zd)
    lsb = float(np.float32(LSB))
    x, y, z, m, m_inv = ref.calibration_matrix(xd * lsb, zd * lsb)
    np.testing.assert_allclose(c.x_axis, x, atol=2e-6)
    np.testing.assert_allclose(c.z_axis, z, atol=2e-6)
    np.testing.assert_allclose(c.y_axis, y, atol=2e-6)
    np.testing.assert_allclose(c.m, m, atol=2e-6)
    np.testing.assert_allclose(c.m_inv, m_inv, atol=5e-6)
    np.testing.assert_allclose(c.da_s_g, ref.resolution_in_s(m_inv, [LSB] * 3), rtol=1e-5)
    # against the simulated chip: M = R_SA^T, recovered to well under a resolution step
    np.testing.assert_allclose(node.true_m, ref.chip_rotation(CHIP).T, atol=1e-15)
    assert np.max(np.abs(c.m - node.true_m)) < 1e-3
    assert abs(c.capture["x_dot_z"]) < 1e-3


def test_constrained_mean_has_the_mean_magnitude_and_the_plain_mean_direction():
    s = _random_capture(99)
    cm = ref.constrained_mean(s)
    assert np.linalg.norm(cm) == pytest.approx(np.mean(np.linalg.norm(s, axis=1)), rel=1e-12)
    np.testing.assert_allclose(ref.unit(cm), ref.unit(s.mean(axis=0)), atol=1e-14)


# ---- Acceptance grid ----------------------------------------------------------------------

@pytest.mark.parametrize("noise", [0.0, 0.5 * LSB, LSB])
def test_grid_calibrated_error_within_eq22_bound(noise):
    """Grid +-3 deg camber x +-10 deg psi, chip misaligned by (2, -1.5, 2.5) deg, 4 mg LSB,
    int16 quantisation, noise as parametrised, 256-sample windows.

    How eq. 22 applies to a window mean: it bounds |d theta| (to first order) when every S-axis
    error of the mean is at most da. Rounding keeps each sample's quantisation error within
    LSB/2, hence also the mean's; averaging shrinks the noise to noise/16 and the calibration
    (2 x 2048 samples) leaves a small residual rotation. The bound published with each result
    uses da = |M^-1| LSB. The test checks both the premise (per-axis error of the calibrated
    mean vs truth <= da_S) and the claim (|theta error| <= bound) at every grid point, and that
    the uncalibrated device breaks the bound.
    """
    node = CamberNode(chip=CHIP, noise_std_g=noise, seed=21)
    cal = calibrate(node.capture(2048, "x_down"), node.capture(2048, "z_down"))
    ident = Calibration.identity()
    rows = []
    for th in np.radians(np.linspace(-3, 3, 7)):
        for ps in np.radians(np.linspace(-10, 10, 9)):
            node.set_wheel(th, ps)
            truth_s = node.reading_s()
            w = node.capture(256)
            r = measure(w, cal)
            u = measure(w, ident)
            assert r.ok and u.ok
            axis_ratio = np.max(np.abs(np.array(r.a_s_g) - truth_s) / cal.da_s_g)
            rows.append((th, ps, abs(r.theta - th), r.bound, abs(u.theta - th), u.bound, axis_ratio,
                         abs(r.psi - ps)))
    a = np.array(rows)
    print(f"\nnoise {noise * 1000:.0f} mg: calibrated max |err| {math.degrees(a[:, 2].max()):.4f} deg "
          f"(max err/bound {np.max(a[:, 2] / a[:, 3]):.3f}, bound {math.degrees(a[:, 3].min()):.4f}.."
          f"{math.degrees(a[:, 3].max()):.4f} deg); uncalibrated max |err| {math.degrees(a[:, 4].max()):.3f} deg "
          f"(min err/bound {np.min(a[:, 4] / a[:, 5]):.2f}); max per-axis err/da {a[:, 6].max():.3f}; "
          f"max psi err {math.degrees(a[:, 7].max()):.4f} deg")
    assert np.all(a[:, 6] <= 1.0)  # premise of eq. 22
    assert np.all(a[:, 2] <= a[:, 3])  # calibrated: within the bound everywhere
    assert np.any(a[:, 4] > a[:, 5])  # uncalibrated: outside the bound somewhere
    assert a[:, 4].max() > 1.0 * DEG


def test_c_measure_matches_reference_on_the_window(calibrated):
    node, cal = calibrated
    node.set_wheel(-2.0 * DEG, 6.0 * DEG)
    w = node.capture(300)
    r = measure(w, cal)
    assert r.ok and r.n == 300
    mean_a = w.mean(axis=0) * float(np.float32(LSB))
    a_s = cal.m_inv @ mean_a
    np.testing.assert_allclose(r.a_s_g, a_s, atol=2e-6)
    assert r.theta == pytest.approx(ref.theta_eq6(a_s), abs=3e-6)
    assert r.psi == pytest.approx(ref.psi_eq4(a_s), abs=3e-6)
    assert r.mag_g == pytest.approx(np.linalg.norm(a_s), abs=2e-6)
    assert r.std_g == pytest.approx(np.sqrt(np.sum(np.var(w * LSB, axis=0))), rel=1e-4)
    expect_bound = ref.worst_case_error(r.theta, r.psi, ref.resolution_in_s(cal.m_inv, [LSB] * 3), r.mag_g)
    assert r.bound == pytest.approx(expect_bound, rel=1e-5)


# ---- Refusals (reason codes) ----------------------------------------------------------------

def test_reasons(calibrated):
    node, cal = calibrated
    node.set_wheel(1.0 * DEG, 3.0 * DEG)
    w = node.capture(256)
    assert measure(w, cal).reason == Reason.OK
    r = measure(w, None)
    assert r.reason == Reason.NOT_CALIBRATED and r.theta is None and "calibration" in r.message
    r = measure(w[:10], cal)
    assert r.reason == Reason.TOO_FEW_SAMPLES and r.theta is None and "10 samples" in r.message
    assert measure(np.zeros((0, 3), np.int16), cal).reason == Reason.TOO_FEW_SAMPLES
    flags = np.ones(256, bool)
    flags[100] = False
    assert measure(w, cal, stationary=flags).reason == Reason.NOT_STATIONARY_FLAG
    assert measure(w, cal, stationary=False).reason == Reason.NOT_STATIONARY_FLAG
    sat = w.copy()
    sat[7, 1] = 32767
    assert measure(sat, cal).reason == Reason.SATURATED
    # vibrating: 0.1 g at 1/8 of the sample rate on the device's y axis
    chunks = []
    for i in range(256):
        node.set_disturbance([0.0, 0.1 * math.sin(2 * math.pi * i / 8), 0.0])
        chunks.append(node.capture(1))
    r = measure(np.vstack(chunks), cal)
    assert r.reason == Reason.MOVING and r.std_g > 0.03 and "moving" in r.message
    # a steady 0.1 g acceleration: steady window, but not gravity alone
    node.set_disturbance([0.0, 0.0, 0.1])  # along gravity: reads 0.9 g
    r = measure(node.capture(256), cal)
    assert r.reason == Reason.MAGNITUDE and r.theta is None and abs(r.mag_g - 1) > 0.05
    node.set_disturbance([0.0, 0.0, 0.0])
    # precedence: the caller's flag outranks the data checks
    assert measure(np.vstack(chunks), cal, stationary=False).reason == Reason.NOT_STATIONARY_FLAG


def test_measure_windows_blocks(calibrated):
    node, cal = calibrated
    node.set_wheel(0.5 * DEG, -4.0 * DEG)
    w = node.capture(1000)
    flags = np.ones(1000, bool)
    flags[300] = False  # taints the second window only
    res = measure_windows(w, cal, stationary=flags, config=MeasureConfig(window=250))
    assert [r.reason for r in res] == [Reason.OK, Reason.NOT_STATIONARY_FLAG, Reason.OK, Reason.OK]
    assert measure_windows(w[:999], cal, config=MeasureConfig(window=250))[-1].n == 250
    assert len(measure_windows(w[:999], cal, config=MeasureConfig(window=250))) == 3
    single = measure(w[:250], cal)
    assert res[0].theta == single.theta and res[0].bound == single.bound


def test_c_init_rejects_bad_config_and_calibration():
    cfg = ffi.new("vh_camber_config_t *")
    lib.vh_camber_config_default(cfg)
    inst = ffi.new("vh_camber_t *")
    assert lib.vh_camber_init(inst, cfg, ffi.NULL) == lib.VH_OK
    out = ffi.new("vh_camber_result_t *")
    lib.vh_camber_evaluate(inst, out)
    assert out.reason == lib.VH_CAMBER_NOT_CALIBRATED
    for field, value in (("min_samples", 1), ("window", 8), ("mag_tol_g", 0.0), ("std_max_g", float("nan"))):
        bad = ffi.new("vh_camber_config_t *", cfg[0])
        setattr(bad, field, value)
        assert lib.vh_camber_init(inst, bad, ffi.NULL) == lib.VH_EINVAL, field
    cal = ffi.new("vh_camber_cal_t *")
    lsb = f3([LSB] * 3)
    assert lib.vh_camber_cal_from_axes(cal, f3([1, 0, 0]), f3([0, 0, 1]), lsb, 0.0175) == lib.VH_OK
    assert cal.valid == 1 and list(cal.y_axis) == [0.0, 1.0, 0.0]
    for x, z in (([1, 0, 0], [1, 0, 0]), ([1.1, 0, 0], [0, 0, 1]), ([float("nan"), 0, 0], [0, 0, 1]),
                 ([1, 0, 0], [0.05, 0, 0.99875])):
        assert lib.vh_camber_cal_from_axes(cal, f3(x), f3(z), lsb, 0.0175) == lib.VH_EINVAL
        assert cal.valid == 0
        assert lib.vh_camber_set_calibration(inst, cal) == lib.VH_EINVAL
    assert lib.vh_camber_cal_from_axes(cal, f3([1, 0, 0]), f3([0, 0, 1]), f3([0, LSB, LSB]), 0.0175) == lib.VH_EINVAL
    with pytest.raises(ConfigError, match="window"):
        measure_windows(np.zeros((10, 3), np.int16), None, config=MeasureConfig(window=5))


# ---- Bad captures -----------------------------------------------------------------------------

def test_bad_captures_are_rejected_with_reasons():
    node = CamberNode(chip=CHIP, seed=3)
    xd, zd = node.capture(256, "x_down"), node.capture(256, "z_down")
    calibrate(xd, zd)
    with pytest.raises(CaptureError, match="x-down capture has 10 samples; at least 64"):
        calibrate(xd[:10], zd)
    with pytest.raises(CaptureError, match="x and z axes not orthogonal"):
        calibrate(xd, xd)
    with pytest.raises(CaptureError, match="magnitude .* from 1 g"):
        calibrate(xd, zd, lsb_g=0.008)
    sat = zd.copy()
    sat[3] = [0, 0, 32767]
    with pytest.raises(CaptureError, match="z-down capture: 1 samples at the int16 limits"):
        calibrate(xd, sat)
    shaky = []
    rng = np.random.default_rng(0)
    for _ in range(256):
        node.set_disturbance(rng.normal(scale=0.05, size=3))
        shaky.append(node.capture(1, "z_down"))
    node.set_disturbance([0, 0, 0])
    with pytest.raises(CaptureError, match="z-down capture spread .* the device moved"):
        calibrate(xd, np.vstack(shaky))
    # a fixture 3 deg off square: z-down data tilted about y
    tilt = ref.rot_w_s(3 * DEG)
    zt = np.round((tilt @ ref.unit(node.true_m @ [0, 0, 1])) / LSB + rng.normal(scale=1, size=(256, 3)))
    with pytest.raises(CaptureError, match=r"deg off square"):
        calibrate(xd, zt)
    assert issubclass(CaptureError, ConfigError)
    for bad, msg in ((xd[:, :2], "shape"), (xd * 0.004, "raw integer counts"),
                     (np.full((100, 3), np.nan), "NaN"), (xd.astype(np.int32) * 200, "int16 range"),
                     (xd.astype(bool), "integer counts")):
        with pytest.raises(CaptureError, match=msg):
            calibrate(bad, zd)
    with pytest.raises(ConfigError, match="lsb_g"):
        calibrate(xd, zd, lsb_g=-1)
    with pytest.raises(CaptureError, match="at least 300"):
        calibrate(xd, zd, limits=CalibrationLimits(min_samples=300))


# ---- Calibration file -----------------------------------------------------------------------

def test_file_round_trip_per_wheel(tmp_path, calibrated):
    node, cal = calibrated
    path = tmp_path / "camber_cal.json"
    cal.save(path, "FL")
    other = Calibration.identity()
    other.save(path, "RR")
    doc = json.loads(path.read_text())
    assert doc["format"] == camber.FORMAT and doc["version"] == camber.VERSION
    assert sorted(doc["wheels"]) == ["FL", "RR"]
    back = Calibration.load(path, "FL")
    assert back == cal
    np.testing.assert_array_equal(back.m_inv, cal.m_inv)  # float32 axes survive JSON exactly
    node.set_wheel(1.2 * DEG, 5 * DEG)
    w = node.capture(256)
    assert measure(w, back) == measure(w, cal)
    assert Calibration.load(path, "RR") == other
    cal.save(path, "RR")  # update one wheel, keep the other
    assert camber.load_calibrations(path) == {"FL": cal, "RR": cal}
    with pytest.raises(ConfigError, match="no calibration for wheel FR"):
        Calibration.load(path, "FR")
    with pytest.raises(ConfigError, match="wheel must be one of"):
        cal.save(path, "front")


def _good_doc(cal):
    return {"format": camber.FORMAT, "version": 1, "wheels": {"FL": cal.to_dict()}}


@pytest.mark.parametrize("mutate, msg", [
    (lambda d: d.update(format="something-else"), "not a camber calibration file"),
    (lambda d: d.update(version=2), "unsupported version 2 .written by a newer"),
    (lambda d: d.update(version="1"), "version must be an integer"),
    (lambda d: d.pop("version"), "version must be an integer"),
    (lambda d: d.update(extra=1), "unknown top-level key"),
    (lambda d: d.update(wheels={}), "non-empty object"),
    (lambda d: d["wheels"].update(XX=d["wheels"]["FL"]), "unknown wheel 'XX'"),
    (lambda d: d["wheels"]["FL"].pop("z_axis"), "wheels.FL: missing key 'z_axis'"),
    (lambda d: d["wheels"]["FL"].update(z_axes=[0, 0, 1]), "unknown key.*z_axes"),
    (lambda d: d["wheels"]["FL"].update(x_axis=[1, 0]), "x_axis: expected a list of 3"),
    (lambda d: d["wheels"]["FL"].update(x_axis=[1, 0, True]), "x_axis: expected 3 finite"),
    (lambda d: d["wheels"]["FL"].update(x_axis=[float("nan"), 0, 0]), "x_axis: expected 3 finite"),
    (lambda d: d["wheels"]["FL"].update(x_axis=[0.9, 0, 0]), "x_axis must be a unit vector"),
    (lambda d: d["wheels"]["FL"].update(x_axis=[0.99875, 0, 0.05]), "not orthogonal"),
    (lambda d: d["wheels"]["FL"].update(y_axis=[0, 1, 0.001]), "y_axis is not z_axis x x_axis"),
    (lambda d: d["wheels"]["FL"].update(lsb_g=[0.004, 0, 0.004]), "lsb_g must be 3 finite numbers"),
    (lambda d: d["wheels"]["FL"].update(capture=[]), "capture: expected an object"),
])
def test_bad_calibration_files_are_rejected(tmp_path, mutate, msg):
    cal = Calibration.identity()
    doc = _good_doc(cal)
    mutate(doc)
    path = tmp_path / "cal.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ConfigError, match=msg):
        camber.load_calibrations(path)


def test_unreadable_files_and_no_clobber(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        camber.load_calibrations(tmp_path / "missing.json")
    p = tmp_path / "bad.json"
    p.write_text("{not json")
    with pytest.raises(ConfigError, match="not JSON"):
        camber.load_calibrations(p)
    p.write_text("[1, 2]")
    with pytest.raises(ConfigError, match="JSON object"):
        camber.load_calibrations(p)
    # saving into a file that is not a valid calibration refuses and leaves it alone
    p.write_text('{"format": "other"}')
    with pytest.raises(ConfigError, match="not a camber calibration file"):
        Calibration.identity().save(p, "FL")
    assert p.read_text() == '{"format": "other"}'
    assert sorted(x.name for x in tmp_path.iterdir()) == ["bad.json"]  # no temp files left


# ---- Node simulation ------------------------------------------------------------------------

def test_node_truth_noise_and_determinism():
    th, ps = 2.0 * DEG, -7.0 * DEG
    node = CamberNode(theta=th, psi=ps, chip=CHIP, noise_std_g=0.01, bias_g=(0.002, 0, 0), seed=9)
    np.testing.assert_allclose(node.reading_s(), ref.gravity_s(th, ps), atol=1e-15)
    np.testing.assert_allclose(node.reading_s("x_down"), [1, 0, 0])
    np.testing.assert_allclose(node.reading_s("z_down"), [0, 0, 1])
    w = node.capture(20000)
    expect = node.true_m @ ref.gravity_s(th, ps) + [0.002, 0, 0]
    np.testing.assert_allclose(w.mean(axis=0) * LSB, expect, atol=4 * 0.01 / math.sqrt(20000))
    np.testing.assert_allclose(w.std(axis=0) * LSB, 0.01 * math.sqrt(1 + 1 / 12 * (LSB / 0.01) ** 2), rtol=0.03)
    again = CamberNode(theta=th, psi=ps, chip=CHIP, noise_std_g=0.01, bias_g=(0.002, 0, 0), seed=9)
    np.testing.assert_array_equal(again.capture(20000), w)
    other = CamberNode(theta=th, psi=ps, chip=CHIP, noise_std_g=0.01, bias_g=(0.002, 0, 0), seed=10)
    assert not np.array_equal(other.capture(100), w[:100])
    quiet = CamberNode(theta=th, psi=ps, noise_std_g=0.0)
    np.testing.assert_array_equal(quiet.capture(3), np.tile(np.floor(ref.gravity_s(th, ps) / LSB + 0.5), (3, 1)))
    big = CamberNode(noise_std_g=0.0, lsb_g=1e-5)  # 1 g = 100000 counts: saturates
    assert big.capture(1, "z_down")[0, 2] == 32767
    with pytest.raises(ConfigError):
        CamberNode(lsb_g=0.0)
    with pytest.raises(ConfigError, match="pose"):
        node.capture(1, "upside_down")


# ---- MCU realism --------------------------------------------------------------------------

def test_firmware_is_single_precision_only(tmp_path):
    """The firmware source compiles with double promotion and float conversions as errors
    and never names `double`: the float32 claim of docs/camber.md holds."""
    src = ROOT / "c_core" / "camber" / "vh_camber.c"
    code = re.sub(r"/\*.*?\*/", "", src.read_text(), flags=re.S)
    assert "double" not in code and "malloc" not in code
    cc = (sysconfig.get_config_var("CC") or "cc").split()[0]
    if shutil.which(cc) is None:
        pytest.skip(f"no C compiler {cc!r}")
    subprocess.run([cc, "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-Wdouble-promotion",
                    "-Wfloat-conversion", "-Wconversion", "-I", str(ROOT / "c_core" / "common"), "-c", str(src),
                    "-o", str(tmp_path / "vh_camber.o")], check=True)
