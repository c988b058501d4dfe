"""Sliding-mode active roll control (c_core/roll, seed 003 eq. 27-35): limits, boundary layer,
passive mode, fade-out on bad estimator health. The closed loop here runs on the estimator's own
9-DOF model (vehest_can.systems.roll.evaluate.closed_loop_model), with the UKF's estimates."""
import numpy as np
import pytest

from vehest_can.systems.roll import api as rn
from vehest_can.systems.roll import evaluate as ev

H = rn.lib
DT = 0.001


@pytest.fixture(scope="module")
def loops():
    return {
        "passive": ev.closed_loop_model(72.0, active=False),
        "active": ev.closed_loop_model(72.0, active=True),
        "sgn": ev.closed_loop_model(72.0, active=True, smc_over={"p": 1e-6}),
    }


def test_init_refuses_bad_gains():
    sp = rn.default_smc_params()
    sp.p = 0.0
    with pytest.raises(rn.RollError):
        rn.Smc(sp)
    sp = rn.default_smc_params()
    sp.fade_time = 0.5 * sp.m_max_f / sp.rate_max_f   # a fade the rate limit cannot follow
    with pytest.raises(rn.RollError):
        rn.Smc(sp)


@pytest.mark.parametrize("prec", list(rn.PRECISIONS))
def test_torque_and_rate_limits_hold_under_any_demand(prec):
    sp = rn.default_smc_params()
    c = rn.Smc(sp, prec)
    rng = np.random.default_rng(1)
    n = 3000
    t = np.arange(n) * DT
    phi = 0.2 * np.sign(np.sin(2 * np.pi * 0.7 * t)) + rng.normal(0, 0.02, n)   # demands far
    p = rng.normal(0, 0.5, n)                                                     # beyond the limits
    ay = rng.normal(0, 10.0, n)
    mf, mr, h, _ = c.run(phi, p, ay, H.VH_ROLL_H_OK, True)
    tol = 1e-3
    assert np.abs(mf).max() <= sp.m_max_f + tol and np.abs(mr).max() <= sp.m_max_r + tol
    assert np.abs(np.diff(mf)).max() <= sp.rate_max_f * DT * (1 + 1e-6) + tol
    assert np.abs(np.diff(mr)).max() <= sp.rate_max_r * DT * (1 + 1e-6) + tol
    assert np.any(h & H.VH_ROLL_S_SAT) and np.any(h & H.VH_ROLL_S_RATE)
    assert c.c.sat_steps > 0 and c.c.rate_steps > 0


def test_front_rear_split_is_the_roll_stiffness_ratio():
    prm = rn.default_params()
    sp = rn.default_smc_params(prm)
    assert sp.front_share == pytest.approx(prm.kphi_f / (prm.kphi_f + prm.kphi_r))
    c = rn.Smc(sp)
    mf, mr, _, _ = c.run(np.full(2000, 0.01), np.zeros(2000), np.full(2000, 3.0), H.VH_ROLL_H_OK, True)
    assert mf[-1] / (mf[-1] + mr[-1]) == pytest.approx(sp.front_share, rel=1e-9)


def test_passive_mode_gives_zero_moment(loops):
    assert np.all(loops["passive"].m_cmd == 0)
    assert np.all(loops["passive"].smc_health & H.VH_ROLL_S_PASSIVE)


def test_active_reduces_peak_roll_on_the_model(loops):
    pas = np.abs(loops["passive"].x[:, 4]).max()
    act = np.abs(loops["active"].x[:, 4]).max()
    print(f"72 km/h on the 9-DOF model: peak roll passive {np.degrees(pas):.3f} deg, active "
          f"{np.degrees(act):.3f} deg ({100 * (1 - act / pas):.1f} % less)")
    assert act <= 0.5 * pas


def test_boundary_layer_removes_chattering(loops):
    tv_a, hf_a = ev.chatter_figures(loops["active"].m_cmd.sum(1), DT)
    tv_s, hf_s = ev.chatter_figures(loops["sgn"].m_cmd.sum(1), DT)
    tv_p, hf_p = ev.chatter_figures(loops["passive"].m_cmd.sum(1), DT)
    peak = np.abs(loops["active"].m_cmd.sum(1)).max()
    print(f"total variation of the moment: passive {tv_p:.0f} Nm, boundary layer {tv_a:.0f} Nm "
          f"({tv_a / peak:.1f} x its peak), sgn (p -> 0) {tv_s:.0f} Nm; energy above 50 Hz: "
          f"{100 * hf_a:.3f} % vs sgn {100 * hf_s:.3f} %")
    assert tv_a < 0.5 * tv_s
    assert tv_a < 10 * peak
    assert hf_a < 0.01
    rate = np.mean(loops["active"].smc_health & H.VH_ROLL_S_RATE > 0)
    rate_s = np.mean(loops["sgn"].smc_health & H.VH_ROLL_S_RATE > 0)
    assert rate < 0.1 < rate_s   # the sgn law lives on the rate limit


def test_controller_uses_the_estimate_and_holds_the_reference(loops):
    """Steady state: roll near the reference (a fraction of the passive roll), from estimates."""
    a = loops["active"]
    pas = loops["passive"].x[-1, 4]
    assert 0.25 * pas < a.x[-1, 4] < 0.5 * pas


@pytest.mark.parametrize("prec", list(rn.PRECISIONS))
def test_fade_out_when_the_estimator_is_not_ok(prec):
    sp = rn.default_smc_params()
    c = rn.Smc(sp, prec)
    n = 3000
    health = np.full(n, H.VH_ROLL_H_OK)
    health[1500:] = H.VH_ROLL_H_DEGRADED        # e.g. a masked (dead) sensor from 1.5 s
    mf, mr, h, _ = c.run(np.full(n, 0.02), np.zeros(n), np.full(n, 5.0), health, True)
    m = mf + mr
    assert abs(m[1499]) > 1000                      # fully on before
    k_deb = int(round(sp.not_ok_debounce / DT))
    k_fade = int(round(sp.fade_time / DT))
    assert np.all(h[1500:] & H.VH_ROLL_S_EST_NOT_OK)
    np.testing.assert_allclose(m[1500:1500 + k_deb - 1], m[1499], rtol=1e-3)  # debounce: fade held
    assert np.all(h[1500 + k_deb + 1:] & H.VH_ROLL_S_TRIPPED)
    assert np.all(np.abs(m[1500:]) <= abs(m[1499]) + 1e-6)
    assert np.all(m[1500 + k_deb + k_fade + 2:] == 0)   # faded out within fade_time after the trip
    assert np.all(h[1500 + k_deb + 2:1500 + k_deb + k_fade - 1] & H.VH_ROLL_S_FADING)
    # smooth: within the rate limits all the way down
    assert np.abs(np.diff(mf[1499:])).max() <= sp.rate_max_f * DT + 1e-3


def test_a_short_not_ok_blip_does_not_fade():
    """A lost frame or two (a few ms of DEGRADED) stays within the debounce: no fade, no trip."""
    sp = rn.default_smc_params()
    c = rn.Smc(sp)
    n = 2000
    health = np.full(n, H.VH_ROLL_H_OK)
    health[1500:1505] = H.VH_ROLL_H_DEGRADED
    mf, mr, h, _ = c.run(np.full(n, 0.02), np.zeros(n), np.full(n, 5.0), health, True)
    assert not np.any(h & H.VH_ROLL_S_TRIPPED & (np.arange(n) > 1200).astype(np.uint32) * 0xFF)
    assert np.all(h[1500:1505] & H.VH_ROLL_S_EST_NOT_OK) and abs(mf[-1]) > 500
    assert np.all(np.abs(mf[1500:1506] - mf[1499]) < 1e-9)


def test_a_filter_reset_trips_at_once():
    sp = rn.default_smc_params()
    c = rn.Smc(sp)
    n = 2000
    health = np.full(n, H.VH_ROLL_H_OK)
    health[1500] = H.VH_ROLL_H_RESET
    mf, mr, h, _ = c.run(np.full(n, 0.02), np.zeros(n), np.full(n, 5.0), health, True)
    assert h[1500] & H.VH_ROLL_S_TRIPPED and abs(mf[1501]) < abs(mf[1499])
    k_rec = int(round(sp.recover_time / DT))
    assert np.all(h[1501:1500 + k_rec] & H.VH_ROLL_S_TRIPPED)


def test_comes_back_only_after_the_estimator_is_ok_for_recover_time():
    sp = rn.default_smc_params()
    c = rn.Smc(sp)
    n = 3000
    health = np.full(n, H.VH_ROLL_H_RESET)
    health[1000:] = H.VH_ROLL_H_OK
    mf, mr, h, _ = c.run(np.full(n, 0.02), np.zeros(n), np.full(n, 5.0), health, True)
    k_rec = int(round(sp.recover_time / DT))
    assert np.all(mf[: 1000 + k_rec - 1] == 0)
    assert abs(mf[-1]) > 0


def test_at_power_on_the_first_ok_estimate_ends_the_trip():
    """The filter's INIT is its settling: after nothing but INIT the moment fades in from the first OK
    step; once a fault was seen (a RESET, above) only after OK for recover_time."""
    sp = rn.default_smc_params()
    n = 1500
    health = np.full(n, H.VH_ROLL_H_INIT)
    health[100:] = H.VH_ROLL_H_OK
    mf, mr, h, _ = rn.Smc(sp).run(np.full(n, 0.02), np.zeros(n), np.full(n, 5.0), health, True)
    assert np.all(mf[:100] == 0) and np.all(h[:100] & H.VH_ROLL_S_TRIPPED)
    assert not np.any(h[100:] & H.VH_ROLL_S_TRIPPED) and abs(mf[110]) > 0
    health[300:310] = H.VH_ROLL_H_RESET  # a fault after the start: the hysteresis applies again
    mf, mr, h, _ = rn.Smc(sp).run(np.full(n, 0.02), np.zeros(n), np.full(n, 5.0), health, True)
    k_rec = int(round(sp.recover_time / DT))
    assert np.all(h[310:310 + k_rec - 1] & H.VH_ROLL_S_TRIPPED) and not h[310 + k_rec + 1] & H.VH_ROLL_S_TRIPPED


def test_bad_estimate_inputs_hold_zero_demand():
    c = rn.Smc()
    mf, mr, h, _ = c.run(np.full(10, np.nan), np.zeros(10), np.zeros(10), H.VH_ROLL_H_OK, True)
    assert np.all(mf == 0) and np.all(h & H.VH_ROLL_S_BAD_INPUT)


def test_closed_loop_fades_on_a_forced_estimator_fault():
    r = ev.closed_loop_model(72.0, active=True, duration_s=3.0,
                             health_override=lambda k, h: H.VH_ROLL_H_RESET if k >= 2000 else h)
    sp = rn.default_smc_params()
    m0 = np.abs(r.m_cmd[1999])
    assert m0.sum() > 1000
    # zero within fade_time (>= m_max / rate_max: the rate limit can follow the fade)
    k_end = int(round(sp.fade_time / DT)) + 2
    assert np.abs(r.m_cmd[2000 + k_end:]).max() == 0
    # inside the fade's envelope: the torque bound shrinks linearly to zero
    j = np.arange(len(r.m_cmd) - 2000)
    env = np.clip(1.0 - (j + 1) * DT / sp.fade_time, 0.0, 1.0) * sp.m_max_f + sp.rate_max_f * DT
    assert np.all(np.abs(r.m_cmd[2000:, 0]) <= env + 1e-3)
    assert np.all(r.smc_health[2000:] & H.VH_ROLL_S_EST_NOT_OK)


# ---- the robust law (docs/roll.md, "The robust law") ----------------------------------------------

def _robust_params():
    sp = rn.default_smc_params()
    rn.lib.vh_roll_smc_law_robust(sp)
    return sp


def test_robust_law_is_the_robust_variants_default_and_the_paper_law_stays_reachable():
    prm = rn.default_params()
    assert rn.default_smc_params(prm).law == H.VH_ROLL_L_PAPER   # the paper's UKF: the paper's SMC
    prm.variant = H.VH_ROLL_V_ROBUST
    sp = rn.default_smc_params(prm)
    assert sp.law == H.VH_ROLL_L_ROBUST and sp.dist_gain == 0.0
    # the actuator turns the body against the suspension alone: sum share_i k_phi,i / k_susp,i
    ksf = 1 / (1 / prm.kphi_f - 1 / (2 * prm.kt * prm.tf ** 2))
    ksr = 1 / (1 / prm.kphi_r - 1 / (2 * prm.kt * prm.tr ** 2))
    assert sp.eta == pytest.approx(sp.front_share * prm.kphi_f / ksf + (1 - sp.front_share) * prm.kphi_r / ksr)
    assert 0.6 < sp.eta < 0.75


@pytest.mark.parametrize("prec", list(rn.PRECISIONS))
def test_robust_law_does_not_feed_the_roll_stiffness_back(prec):
    """With the switching term and the integral off, what is left is the equivalent control: the
    paper's commands +(k_phi - ms g e) phi (it cancels the model's stiffness through the actuator),
    the robust law's holds the reference and does not move with the roll."""
    n = 1500  # on after recover_time, faded in over fade_time
    slopes = {}
    for law, sp in (("paper", rn.default_smc_params()), ("robust", _robust_params())):
        sp.k, sp.ki = 1e-9, 0.0
        m = []
        for phi in (0.0, 0.01):
            c = rn.Smc(sp, prec)
            mf, mr, _, _ = c.run(np.full(n, phi), np.zeros(n), np.zeros(n), H.VH_ROLL_H_OK, True)
            m.append(mf[-1] + mr[-1])
        slopes[law] = (m[1] - m[0]) / 0.01
    sp = rn.default_smc_params()
    assert slopes["paper"] == pytest.approx(sp.kphi - sp.ms_e * 9.81, rel=1e-3)
    assert abs(slopes["robust"]) < 1.0


@pytest.mark.parametrize("prec", list(rn.PRECISIONS))
def test_robust_law_does_not_wind_up_in_a_sustained_turn_with_a_biased_rate(prec):
    """30 s of a steady turn whose roll-rate estimate is biased by 0.5 deg/s: the integral is on the
    angle, bounded, so the command settles and stays within the integral's share of the limits."""
    sp = _robust_params()
    c = rn.Smc(sp, prec)
    n = 30000
    mf, mr, h, _ = c.run(np.full(n, 0.01), np.full(n, np.radians(0.5)), np.full(n, 6.0), H.VH_ROLL_H_OK, True)
    m = mf + mr
    assert np.all(np.isfinite(m)) and not np.any(h[5000:] & (H.VH_ROLL_S_SAT | H.VH_ROLL_S_RATE))
    assert abs(m[-1] - m[20000]) < 1.0                       # settled: no drift over the last 10 s
    assert abs(sp.i_roll * sp.ki * c.c.z) <= sp.i_frac * (sp.m_max_f + sp.m_max_r) * (1 + 1e-6)
    # and the integral is emptied when the controller is off
    mf, mr, _, _ = c.run(np.full(2000, 0.01), np.zeros(2000), np.full(2000, 6.0), H.VH_ROLL_H_OK, False)
    assert c.c.z == 0.0 and mf[-1] == 0.0


@pytest.mark.parametrize("prec", list(rn.PRECISIONS))
def test_robust_law_fades_out_when_the_estimator_is_not_ok(prec):
    sp = _robust_params()
    c = rn.Smc(sp, prec)
    n = 3000
    health = np.full(n, H.VH_ROLL_H_OK)
    health[1500:] = H.VH_ROLL_H_DEGRADED
    mf, mr, h, _ = c.run(np.full(n, 0.02), np.zeros(n), np.full(n, 5.0), health, True)
    k_deb = int(round(sp.not_ok_debounce / DT))
    k_fade = int(round(sp.fade_time / DT))
    assert abs(mf[1499] + mr[1499]) > 1000
    assert np.all(mf[1500 + k_deb + k_fade + 2:] == 0) and np.all(mr[1500 + k_deb + k_fade + 2:] == 0)
    assert np.abs(np.diff(mf)).max() <= sp.rate_max_f * DT + 1e-3
