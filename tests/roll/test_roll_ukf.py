"""Roll UKF (c_core/roll, seed 003 eq. 13-26): the C double build against the independent numpy
reference and filterpy, float32 against double, robust factorisation, resets, masked measurements."""
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from vehest_can.systems.roll import api as rn
from vehest_can.systems.roll import reference as ref

ROOT = Path(__file__).resolve().parents[2]
H = rn.lib


def test_roll_filter_includes_only_the_c_standard_headers():
    """The UKF and SMC (everything in c_core/roll but the ECU application vh_roll_app.*) stand alone:
    they build with c_core/common's float32 functions (vh_mathf.h, the same bits on ECU and host) and
    no other include path."""
    allowed = {"stdint.h", "stddef.h", "math.h", "stdbool.h", "vh_roll.h", "vh_roll_decl.inc", "vh_roll_impl.inc",
               "vh_mathf.h"}
    files = sorted((ROOT / "c_core" / "roll").glob("vh_roll*.[ch]")) + sorted((ROOT / "c_core" / "roll").glob("*.inc"))
    assert len(files) >= 6
    for f in files:
        if f.stem == "vh_roll_app":
            continue
        for inc in re.findall(r'#include\s*[<"]([^">]+)[">]', f.read_text()):
            assert inc in allowed, f"{f.name} includes {inc}"


def test_cdef_is_read_from_the_header():
    sys.path.insert(0, str(ROOT / "c_core"))
    import cbuild

    cdef = cbuild.cdef_of(ROOT / "c_core" / "roll" / "vh_roll.h")  # both precisions, expanded from the template
    for name in ("vh_roll_ukf_step_f32", "vh_roll_ukf_step_f64", "vh_roll_smc_step_f32", "vh_roll_params_t"):
        assert name in cdef


def test_model_at_rest_stays_at_rest():
    for prec in rn.PRECISIONS:
        k = rn.Ukf(prec=prec)
        u = np.array([0.0, 20.0, 0.0, 0.0])
        assert np.all(k.f(np.zeros(rn.NX), u) == 0)
        assert np.all(k.h(np.zeros(rn.NX), u) == 0)


@pytest.mark.parametrize("variant", sorted(rn.VARIANTS))
@pytest.mark.parametrize("gravity", [0, 1])
def test_model_matches_reference_model(variant, gravity):
    prm = rn.make_params(variant=rn.VARIANTS[variant], ay_gravity=gravity)
    k, m = rn.Ukf(prm), ref.RollModel(rn.params_dict(prm))
    rng = np.random.default_rng(3)
    for _ in range(20):
        x = rng.normal(0, 1e-2, rn.NX)
        x[16:] = rng.normal(0, 1.0, rn.NX - 16)   # the disturbances [kN m, kN]; the paper's variant ignores them
        u = np.array([rng.normal(0, 0.05), rng.uniform(5, 30), rng.normal(0, 2000), rng.normal(0, 2000)])
        np.testing.assert_allclose(k.f(x, u), m.f(x, u)[0], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(k.h(x, u), m.h(x, u)[0], rtol=1e-10, atol=1e-12)


def test_init_refuses_bad_parameters():
    with pytest.raises(rn.RollError):
        rn.Ukf(rn.make_params(ms=-1.0))
    with pytest.raises(rn.RollError):
        rn.Ukf(rn.make_params(dt=float("nan")))


def _mask_pattern(n, seed=5):
    rng = np.random.default_rng(seed)
    mask = np.full(n, rn.ALL_VALID, np.uint32)
    drop = rng.random((n, rn.NZ)) < 0.1
    for k in range(n):
        for i in np.flatnonzero(drop[k]):
            mask[k] &= ~np.uint32(1 << int(i))
    mask[50:60] = 0  # a stretch with nothing valid: prediction only
    return mask


@pytest.mark.parametrize("masked", [False, True])
@pytest.mark.parametrize("variant", sorted(rn.VARIANTS))
def test_c_double_agrees_with_numpy_reference(case72, masked, variant):
    _, u, z, _ = case72
    n = 800
    mask = _mask_pattern(n) if masked else None
    prm = rn.make_params(variant=rn.VARIANTS[variant])
    xc, _, _ = rn.Ukf(prm, "f64").run(u[:n], z[:n], mask)
    xr = ref.RefUkf(rn.params_dict(prm)).run(u[:n], z[:n], mask)
    assert np.all(xc[:, xr.shape[1]:] == 0)            # states the variant does not carry
    xc = xc[:, : xr.shape[1]]
    rel = np.max(np.abs(xc - xr), axis=0) / np.max(np.abs(xr), axis=0)
    print(f"C double vs numpy reference, {n} steps, masked={masked}: max relative {rel.max():.2e}")
    assert rel.max() <= 1e-6


def test_the_adaptive_roll_rate_noise_is_the_same_in_c_and_in_the_reference(case72):
    """eq. 18a exercised: R ten times too small makes the NIS per measurement ~10, so the robust
    variant's q_p scale leaves 1; the C double build and the numpy reference still agree, and without
    the adaptation the estimate is another one (the test would see an adaptation done differently)."""
    _, u, z, _ = case72
    n = 600
    r = [v / 10.0 for v in rn.default_params().r]
    prm = rn.make_params(variant=rn.VARIANTS["robust"], r=r)
    c = rn.Ukf(prm, "f64")
    xc = np.array([(c.step(u[k], z[k]), c.x)[1] for k in range(n)])
    assert 2.0 < c.c.nis_lp <= float(prm.qp_adapt_max) * 10
    xr = ref.RefUkf(rn.params_dict(prm)).run(u[:n], z[:n])
    rel = np.max(np.abs(xc[:, : xr.shape[1]] - xr), axis=0) / np.max(np.abs(xr), axis=0)
    assert rel.max() <= 1e-6
    fixed = ref.RefUkf(dict(rn.params_dict(prm), qp_adapt_tau=0.0)).run(u[:n], z[:n])
    assert np.max(np.abs(fixed[:, 5] - xr[:, 5])) > 1e-3 * np.max(np.abs(xr[:, 5]))


def test_a_lateral_model_error_scales_the_lateral_noise_not_the_roll_rates(case72):
    """eq. 18b exercised: only a_y's and r's R ten times too small raise the lateral NIS (2.4 after 3 s)
    while the body-motion NIS stays below 1 (0.68: q_p not scaled); C double and the numpy reference
    agree on the states and both NIS (eq. 18a alone would have scaled q_p by the mixed NIS)."""
    _, u, z, _ = case72
    n = 600
    r = list(rn.default_params().r)
    for i in (0, 13):  # VH_ROLL_Z_AY, VH_ROLL_Z_R
        r[i] /= 10.0
    prm = rn.make_params(variant=rn.VARIANTS["robust"], r=r)
    c = rn.Ukf(prm, "f64")
    xc = np.array([(c.step(u[k], z[k]), c.x)[1] for k in range(n)])
    f = ref.RefUkf(rn.params_dict(prm))
    xr = f.run(u[:n], z[:n])
    rel = np.max(np.abs(xc[:, : xr.shape[1]] - xr), axis=0) / np.max(np.abs(xr), axis=0)
    assert rel.max() <= 1e-6
    assert abs(c.c.nis_lat_lp - f.nis_lat_lp) <= 1e-6 * f.nis_lat_lp
    assert abs(c.c.nis_lp - f.nis_lp) <= 1e-6 * max(f.nis_lp, 1.0)
    print(f"lateral NIS {c.c.nis_lat_lp:.2f}, body-motion NIS {c.c.nis_lp:.2f}")
    assert c.c.nis_lat_lp > 1.5 and c.c.nis_lp < 0.5 * c.c.nis_lat_lp


def test_numpy_reference_agrees_with_filterpy(case72):
    _, u, z, _ = case72
    n = 120
    pd = rn.params_dict(rn.default_params())
    xr = ref.RefUkf(pd).run(u[:n], z[:n])
    fp = ref.filterpy_ukf(pd)
    xf = np.zeros_like(xr)
    for k in range(n):
        ref.filterpy_step(fp, u[k], z[k])
        xf[k] = fp.x
    rel = np.max(np.abs(xf - xr), axis=0) / np.max(np.abs(xr), axis=0)
    print(f"numpy reference vs filterpy UnscentedKalmanFilter, {n} steps: max relative {rel.max():.2e}")
    assert rel.max() <= 1e-6


def test_float32_against_double(case72):
    truth, u, z, idx = case72
    x32, _, h32 = rn.Ukf(prec="f32").run(u, z)
    x64, _, h64 = rn.Ukf(prec="f64").run(u, z)
    d_phi = np.max(np.abs(x32[:, 4] - x64[:, 4]))
    d_p = np.max(np.abs(x32[:, 5] - x64[:, 5]))
    print(f"float32 vs double over {len(u)} steps: max |d phi| {d_phi:.2e} rad, max |d p| {d_p:.2e} rad/s "
          f"(peak phi {np.abs(truth['phi']).max():.4f} rad)")
    n_init = int(np.argmax(h32 != H.VH_ROLL_H_INIT))
    assert np.array_equal(h32, h64) and 0 < n_init < 100      # INIT until converged (43 ms here), then OK
    assert np.all(h32[:n_init] == H.VH_ROLL_H_INIT) and np.all(h32[n_init:] == H.VH_ROLL_H_OK)
    assert d_phi < 1e-5 and d_p < 1e-3


@pytest.mark.parametrize("prec", list(rn.PRECISIONS))
def test_health_is_init_until_the_covariance_has_converged(prec, case72):
    """From the prior P0 the first update leaves the roll rate's sigma at ~2 deg/s (and its error
    at ~1.5 deg/s on the 72 km/h case): INIT, not an estimate to act on. The health leaves INIT
    once sqrt(P) of roll and roll rate are within conv_sd_*, latched until the next reset."""
    truth, u, z, idx = case72
    k = rn.Ukf(prec=prec)
    x, P, h = k.run(u[:100], z[:100])
    first = int(np.argmax(h != H.VH_ROLL_H_INIT))
    assert first > 0 and np.all(h[:first] == H.VH_ROLL_H_INIT) and np.all(h[first:] == H.VH_ROLL_H_OK)
    assert np.sqrt(P[0, 5]) > 10 * k.prm.conv_sd_p                       # the prior's uncertainty
    assert np.sqrt(P[first - 1, 5]) > k.prm.conv_sd_p >= np.sqrt(P[first, 5])
    assert np.sqrt(P[first, 4]) <= k.prm.conv_sd_phi
    err = np.abs(x[:, 5] - truth["p"][idx[:100]])
    assert err[:first].max() > 3 * err[first:].max()                 # what INIT keeps off the bus
    k.set_state(P=-np.eye(rn.NX))                                     # a failed factorisation: reset
    assert k.step(u[100], z[100]) == H.VH_ROLL_H_RESET and k.c.converged == 0
    assert k.step(u[101], z[101]) == H.VH_ROLL_H_INIT                 # converging again from P0
    assert rn.lib.vh_roll_params_check(rn.make_params(conv_sd_p=0.0)) == -1


@pytest.mark.parametrize("prec", list(rn.PRECISIONS))
def test_indefinite_covariance_is_regularised(prec, case72):
    _, u, z, _ = case72
    k = rn.Ukf(prec=prec)
    k.run(u[:100], z[:100])
    n = k.c.n
    P = k.P.astype(float)
    w, V = np.linalg.eigh(P[:n, :n])
    w[0] = -1e-6 * abs(w).max() * 1e-3   # slightly indefinite: the retry's eps fixes it
    P[:n, :n] = (V * w) @ V.T
    k.set_state(P=P)
    h = k.step(u[100], z[100])
    assert k.c.flags & H.VH_ROLL_F_REGULARISED
    assert h == H.VH_ROLL_H_DEGRADED and k.c.resets == 0 and k.c.regularised >= 1
    assert np.all(np.isfinite(k.x))


@pytest.mark.parametrize("prec", list(rn.PRECISIONS))
def test_failed_factorisation_resets_and_flags(prec, case72):
    _, u, z, _ = case72
    k = rn.Ukf(prec=prec)
    k.run(u[:100], z[:100])
    k.set_state(P=-np.eye(rn.NX))
    h = k.step(u[100], z[100])
    assert h == H.VH_ROLL_H_RESET
    assert k.c.flags & H.VH_ROLL_F_CHOL_RESET and k.c.resets == 1
    n = k.c.n
    assert np.all(k.x == 0) and np.allclose(np.diag(k.P)[:n], np.array(list(k.c.p0))[:n])
    assert k.step(u[101], z[101]) == H.VH_ROLL_H_INIT     # from P0 again: not converged yet
    assert k.c.flags_seen & H.VH_ROLL_F_CHOL_RESET


@pytest.mark.parametrize("prec", list(rn.PRECISIONS))
def test_nan_in_state_resets(prec, case72):
    _, u, z, _ = case72
    k = rn.Ukf(prec=prec)
    k.run(u[:50], z[:50])
    x = k.x.astype(float)
    x[3] = np.nan
    k.set_state(x=x)
    assert k.step(u[50], z[50]) == H.VH_ROLL_H_RESET
    assert k.c.flags & H.VH_ROLL_F_NONFINITE and np.all(np.isfinite(k.x))


def test_gross_measurement_fails_the_innovation_test_and_resets(case72):
    _, u, z, _ = case72
    k = rn.Ukf()
    k.run(u[:200], z[:200])
    zz = z[200].copy()
    zz[9] = 5.0  # a 5 m suspension deflection
    assert k.step(u[200], zz) == H.VH_ROLL_H_RESET
    assert k.c.flags & H.VH_ROLL_F_DIVERGED


def test_masked_measurement_is_left_out_not_replaced(case72):
    _, u, z, _ = case72
    bit = 1 << 9  # suspension deflection FL
    a, b = rn.Ukf(), rn.Ukf()
    a.run(u[:300], z[:300])
    b.run(u[:300], z[:300])
    zz = z[300].copy()
    zz[9] = 123.0                      # garbage under the mask
    ha = a.step(u[300], z[300], rn.ALL_VALID & ~bit)
    hb = b.step(u[300], zz, rn.ALL_VALID & ~bit)
    assert ha == hb == H.VH_ROLL_H_DEGRADED
    assert np.array_equal(a.x, b.x) and a.c.n_used == rn.NZ - 1 and a.c.nu[9] == 0
    assert a.c.flags & H.VH_ROLL_F_MASKED


def test_non_finite_measurement_is_masked(case72):
    _, u, z, _ = case72
    a, b = rn.Ukf(), rn.Ukf()
    a.run(u[:100], z[:100])
    b.run(u[:100], z[:100])
    zz = z[100].copy()
    zz[0] = np.nan
    a.step(u[100], zz)
    b.step(u[100], z[100], rn.ALL_VALID & ~1)
    assert np.array_equal(a.x, b.x) and a.c.health == H.VH_ROLL_H_DEGRADED


def test_all_masked_is_prediction_only(case72):
    _, u, z, _ = case72
    k = rn.Ukf()
    k.run(u[:100], z[:100])
    m = ref.RollModel(rn.params_dict(k.prm))
    n = k.c.n
    x0, P0 = k.x.astype(float)[:n], k.P.astype(float)[:n, :n]
    h = k.step(u[100], z[100], 0)
    gamma, w = ref.sigma_weights(n, k.prm.kappa)
    Xf = m.f(ref.sigma_points(x0, P0, gamma), u[100])
    np.testing.assert_allclose(k.x[:n], w @ Xf, rtol=1e-9, atol=1e-12)
    assert h == H.VH_ROLL_H_DEGRADED and k.c.flags & H.VH_ROLL_F_NO_UPDATE


def test_a_dead_sensor_masked_keeps_the_roll_estimate(case72):
    """A dead suspension-deflection sensor, flagged invalid by the RX checks, leaves the update:
    the estimate stays close to the truth on the other 13."""
    truth, u, z, idx = case72
    mask = np.full(len(u), rn.ALL_VALID & ~(1 << 10), np.uint32)
    zz = z.copy()
    zz[:, 10] = 0.0  # dead: stuck at zero, flagged
    x, _, h = rn.Ukf().run(u, zz, mask)
    err = np.sqrt(np.mean((x[:, 4] - truth["phi"][idx]) ** 2)) / np.abs(truth["phi"]).max()
    first = int(np.argmax(h != H.VH_ROLL_H_INIT))
    assert 0 < first < 100 and np.all(h[first:] == H.VH_ROLL_H_DEGRADED) and err < 0.05
