"""The 14-DOF plant's active roll actuators (vh_v14_set_roll_moment) and the loop closed on the
plant with the C float32 UKF + SMC (off the bus: measurements synthesised from the truth)."""
import numpy as np
import pytest

from vehest_can.native import ffi, lib
from vehest_can.systems.roll import evaluate as ev

DT = 0.0005


def _plant(speed=20.0):
    prm = ffi.new("vh_v14_params_t *")
    lib.vh_v14_params_default(prm)
    p = ffi.new("vh_v14_t *")
    assert lib.vh_v14_init(p, prm) == lib.VH_OK
    lib.vh_v14_set_rolling(p, speed)
    return p


def test_zero_moment_is_the_passive_plant_bit_for_bit():
    a, b = _plant(), _plant()
    inp = ffi.new("vh_v14_input_t *")
    lib.vh_v14_input_init(inp, 1.0)
    for k in range(4000):
        inp.steer = 0.05 * min(1.0, k / 2000)
        lib.vh_v14_step(a, inp)
        lib.vh_v14_set_roll_moment(b, 0.0, 0.0)
        lib.vh_v14_step(b, inp)
    assert bytes(ffi.buffer(ffi.addressof(a, "x"))) == bytes(ffi.buffer(ffi.addressof(b, "x")))
    assert a.arc.m[0] == 0.0 and a.arc.m[1] == 0.0


def test_limits_rate_and_lag():
    p = _plant(0.0)
    inp = ffi.new("vh_v14_input_t *")
    lib.vh_v14_input_init(inp, 1.0)
    lib.vh_v14_set_roll_moment(p, 1e5, 1e5)           # far beyond the limit
    m = np.zeros((4000, 2))
    lim = np.zeros((4000, 2))
    for k in range(4000):
        lib.vh_v14_step(p, inp)
        m[k] = (p.arc.m[0], p.arc.m[1])
        lim[k] = (p.arc.lim[0], p.arc.lim[1])
    a = p.arc.prm[0]
    assert np.abs(lim).max() <= a.m_max and np.abs(np.diff(lim, axis=0)).max() <= a.rate_max * DT * (1 + 1e-12)
    assert lim[-1, 0] == a.m_max and lim[-1, 1] == a.m_max
    # first-order lag behind the limited command
    k = 1000
    assert 0 < m[k, 0] < lim[k, 0]
    assert m[-1, 0] == pytest.approx(a.m_max, rel=1e-6)
    # a pure roll moment: the body rolls its way (+ lifts the left), total tyre load unchanged
    assert p.truth.phi > 0.005
    assert sum(p.truth.fz) == pytest.approx(sum(p.fz0), rel=1e-5)   # still settling: 0.02 N


def test_config_refuses_bad_limits():
    p = _plant()
    a = ffi.new("vh_v14_arc_params_t *")
    lib.vh_v14_arc_params_default(a)
    a.rate_max = 0.0
    assert lib.vh_v14_arc_config(p, a, a) == lib.VH_EINVAL
    lib.vh_v14_arc_params_default(a)
    assert lib.vh_v14_arc_config(p, a, a) == lib.VH_OK


@pytest.fixture(scope="module")
def loop72():
    return ev.closed_loop_plant(72.0, active=False), ev.closed_loop_plant(72.0, active=True)


def test_active_halves_the_peak_roll_on_the_plant(loop72):
    pas, act = loop72
    pp, pa = np.abs(pas.truth["phi"]).max(), np.abs(act.truth["phi"]).max()
    rp, ra = np.abs(pas.truth["r"]).max(), np.abs(act.truth["r"]).max()
    ayp, aya = np.abs(pas.truth["ay"]).max(), np.abs(act.truth["ay"]).max()
    print(f"72 km/h on the 14-DOF plant: peak roll {np.degrees(pp):.3f} -> {np.degrees(pa):.3f} deg "
          f"({100 * (1 - pa / pp):.1f} % less); peak yaw rate {np.degrees(rp):.2f} -> {np.degrees(ra):.2f} deg/s; "
          f"peak a_y {ayp:.2f} -> {aya:.2f} m/s^2")
    assert pa <= 0.5 * pp


def test_closed_loop_limits_and_no_chattering(loop72):
    _, act = loop72
    a = ffi.new("vh_v14_arc_params_t *")
    lib.vh_v14_arc_params_default(a)
    assert np.abs(act.m_act).max() <= a.m_max
    assert np.abs(np.diff(act.m_act, axis=0)).max() <= a.rate_max * DT
    tv, hf = ev.chatter_figures(act.m_act.sum(1), DT)
    peak = np.abs(act.m_act.sum(1)).max()
    print(f"applied moment: total variation {tv:.0f} Nm ({tv / peak:.2f} x its peak), energy above 50 Hz {100 * hf:.3f} %")
    assert tv < 3 * peak and hf < 0.01


def test_ukf_stays_on_the_truth_in_active_mode(loop72):
    for r in loop72:
        tr = r.truth
        e_phi = np.sqrt(np.mean((r.xhat[:, 4] - tr["phi"][r.idx]) ** 2))
        e_p = np.sqrt(np.mean((r.xhat[:, 5] - tr["p"][r.idx]) ** 2))
        assert e_phi <= 0.05 * np.abs(tr["phi"]).max()
        assert e_p <= 0.10 * np.abs(tr["p"]).max()
