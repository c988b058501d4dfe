"""SKFMEC-A's contradictions (a published state against a measurement makes the health DEGRADED) and the
tyre from the car file (docs/tireforce.md, "Contradictions", "The tyre from the car file")."""
from dataclasses import replace

import numpy as np
import pytest

from vehest_can.carfile import load_car
from vehest_can.native import lib
from vehest_can.systems.tireforce import adaptive as A
from vehest_can.systems.tireforce import api as tf
from vehest_can.systems.tireforce import report as tr
from vehest_can.systems.tireforce.scenario import load_tireforce_scenario, tireforce_scenario_dir

TS = 5e-4


@pytest.fixture(scope="module")
def paper_run():
    truth, dec, _ = tr.simulate(load_tireforce_scenario("chassis_paper_mu_drop"), variants=())
    return truth, dec


def _first_not_ok(health, k0):
    bad = np.flatnonzero(health[k0:] != A.H_OK)
    return None if bad.size == 0 else bad[0] * TS


def test_biased_and_stuck_torques_are_degraded_the_clean_run_is_not(paper_run):
    """Wheel torques +200 N m on every wheel from 1 s: the mass leaves the balance, DEGRADED 1.9 s later
    (the balance's residual past 1000 N + 25 %), OK for at most 6 % of the rest; stuck at their 1 s
    value: DEGRADED once braking starts without them (v_x leaves the wheels' range). The clean run stays
    OK throughout; never OK while v_x is outside the wheels' range or the mass at its clamp."""
    truth, dec = paper_run
    u = dec.for_filter()
    k0 = int(1.0 / TS)
    clean = A.AdaptiveFixed().run(u, dec.mask, dec.ride)
    assert _first_not_ok(clean.health, 1000) is None
    for kind, within_s, ok_frac in (("bias", 2.5, 0.1), ("stuck", 8.0, 0.9)):
        tq = u.torque.copy()
        tq[k0:] = tq[k0:] + 200.0 if kind == "bias" else tq[k0]
        uu = replace(u, torque=tq)
        fixed = A.AdaptiveFixed().run(uu, dec.mask, dec.ride)
        double = A.AdaptiveSkfmec().run(uu, dec.mask, dec.ride)
        first = _first_not_ok(fixed.health, k0)
        assert first is not None and first <= within_s, (kind, first)
        assert (fixed.health[k0 + 3000:] == A.H_OK).mean() <= ok_frac
        cfg = A.AdaptiveConfig()
        v = tf.SkfConfig.default().rw * uu.omega
        tol = cfg.vx_tol + cfg.vx_tol_rel * v.max(1)
        off = (double.x[:, 0] > v.max(1) + tol) | (double.x[:, 0] < v.min(1) - tol)
        clamp = (double.mass <= cfg.mass_range[0] * tf.SkfConfig.default().m) | \
                (double.mass >= cfg.mass_range[1] * tf.SkfConfig.default().m)
        assert not np.any((double.health == A.H_OK) & (off | clamp))


def test_doubled_torques_are_degraded_where_the_wheels_carry_torque():
    """Wheel torques scaled x2 from 1 s on a run that brakes from 1 s (split-mu, 250/150 N m per wheel,
    about 1.4 m/s^2): DEGRADED 2.5 s later (the mass leaves its balance), OK for at most 20 % of the
    rest (13 % measured). A gain error needs the torque to show: on the paper run (50 N m mean) the
    mass moves 1 % and v_x stays within the wheels' range, so it stays OK there (docs/tireforce.md)."""
    _, dec, _ = tr.simulate(load_tireforce_scenario(tireforce_scenario_dir() / "stress" / "stress_split_mu_braking.toml"),
                            variants=())
    u = dec.for_filter()
    k0 = int(1.0 / TS)
    tq = u.torque.copy()
    tq[k0:] *= 2.0
    fixed = A.AdaptiveFixed().run(replace(u, torque=tq), dec.mask, dec.ride)
    first = _first_not_ok(fixed.health, k0)
    assert first is not None and first <= 3.0, first
    assert (fixed.health[k0 + 6000:] == A.H_OK).mean() <= 0.2


def test_without_the_roll_rate_it_runs_degraded(paper_run):
    """The roll rate marked not available on every step (a car without the sensor): the filter starts (its
    seed takes p = 0) and runs on a_x, a_y and r, DEGRADED throughout; per tyre within 5 % of peak of the
    truth (4.4 % worst; 2.7 % with the roll rate)."""
    truth, dec = paper_run
    mask = dec.mask & ~np.uint8(lib.VH_SKF_Y_P)
    u = dec.for_filter()
    with_p = A.AdaptiveFixed().run(u, dec.mask, dec.ride)
    without = A.AdaptiveFixed().run(u, mask, dec.ride)
    assert np.all(without.health[400:] == A.H_DEGRADED)
    peak = np.abs(np.asarray(truth["fy"])).max(0)
    fy = np.asarray(truth["fy"])
    assert np.all(np.sqrt(((without.fy - fy)[400:] ** 2).mean(0)) / peak < 0.05)
    assert np.all(np.sqrt(((with_p.fy - fy)[400:] ** 2).mean(0)) / peak < 0.03)


def test_the_car_file_carries_its_tyre():
    """paper_mb and CommonRoad's sets carry the multi-body model's PAC2002 tyre and lateral compliance;
    the paper's car the 1987 tyre, no compliance (its constants, and so its frames, unchanged)."""
    for name, model, klt in (("paper", 0, 0.0), ("paper_mb", 1, 1.6430724599974725e-05),
                             ("commonroad_vehicle1", 1, 1.0278264878518764e-05)):
        cfg = A.AdaptiveConfig.for_car(load_car(name))
        assert cfg.tyre_model == model and cfg.tyre_klt == pytest.approx(klt, rel=1e-12)
        A.fixed_params(tf.SkfConfig.for_car(load_car(name)), cfg)
    cfg = A.AdaptiveConfig(tyre_model=1)
    fz = np.array([2000.0, 4000.0, 8000.0])
    f = A.lateral_force(np.full(3, 1.0), fz, cfg)
    assert np.allclose(f / fz, f[0] / fz[0])  # load-proportional: the split is the loads'
    assert A.lateral_force(np.array([1e-3]), np.array([4000.0]), cfg)[0] == pytest.approx(
        21.92 * 4000.0 * np.radians(1e-3), rel=1e-4)  # K_y = p_ky1 F_z


def test_our_plant_plays_the_car_files_pac2002_tyre():
    """A car file with a PAC2002 set: the 14-DOF plant's tyre (C, vh_mftire) gives the curve SKFMEC-A's split
    assumes (numpy, adaptive.lateral_force) at every load and slip; end to end, CommonRoad's vehicle 2 without
    its lateral compliance (which our plant does not model) on the 70 km/h ramp: SKFMEC-A within 5 % of each
    tyre's peak (3.5 % worst measured; 15.5 % with the compliance, 16.4 % when the plant ran its 1987 tyre)."""
    from dataclasses import replace as dc_replace

    from vehest_can.native import ffi

    v2 = load_car("commonroad_vehicle2")
    prm = v2.veh14_params(ffi, lib)
    assert prm.tyre.model == lib.VH_MFT_PAC2002
    cfg = A.AdaptiveConfig.for_car(v2)
    fx, fy = ffi.new("double *"), ffi.new("double *")
    for fz in (1500.0, 4000.0, 9000.0):
        for tan_a in (0.005, 0.05, 0.2):
            lib.vh_mft_eval(ffi.addressof(prm, "tyre"), fz, 1.0, 0.0, tan_a, fx, fy)
            want = A.lateral_force(np.array([np.degrees(np.arctan(tan_a))]), np.array([fz]), cfg)[0]
            assert fy[0] == pytest.approx(want, rel=1e-12)
    car = dc_replace(v2, lateral_compliance_m_per_n=0.0)
    sc = dc_replace(load_tireforce_scenario("chassis_relation_70kph"), car=car)
    truth, _, runs = tr.simulate(sc, variants=("skfmec-a",))
    fy_true = np.asarray(truth["fy"])[400:]
    err = np.sqrt(((runs["skfmec-a"].fy[400:] - fy_true) ** 2).mean(0)) / np.abs(fy_true).max(0)
    print("SKFMEC-A per tyre, % of peak:", np.round(100 * err, 2))
    assert np.all(err < 0.05)
