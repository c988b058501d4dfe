"""SKFMEC-A (systems/tireforce/adaptive.py): the paper's SKFMEC with an online mass estimate and a
load-sensitive split, in double. Its parts against independent references (the RLS against the
batch least-squares solution, the split against the cornering-stiffness ratio), and the whole
against the 14-DOF plant on the paper's scenarios and on stress scenarios that no setting was
chosen on (firmware_sim/scenarios/chassis/stress/). The figures are in docs/results.md."""
import math

import numpy as np
import pytest

from vehest_can.native import ffi, lib
from vehest_can.systems.tireforce import adaptive as A
from vehest_can.systems.tireforce import api as tf
from vehest_can.systems.tireforce import report as tr
from vehest_can.systems.tireforce.scenario import load_tireforce_scenario, tireforce_scenario_dir

STRESS = tireforce_scenario_dir() / A.STRESS_DIR


def test_rls_equals_the_batch_least_squares_solution():
    """Without forgetting and bounds, the recursion is the Bayesian batch solution
    m = (m0/P0 + Σ φ y / σ²) / (1/P0 + Σ φ² / σ²) and P = 1 / (1/P0 + Σ φ² / σ²)."""
    rng = np.random.default_rng(3)
    phi = rng.uniform(-3, 3, 400)
    y = 2014.0 * phi + rng.normal(0, 60, 400)
    m0, p0, r = 1814.0, 360.0**2, 60.0**2
    m, p = m0, p0
    for f, yy in zip(phi, y):
        m, p = A.rls_step(m, p, f, yy, r, 1.0, 0.0, math.inf)
    info = 1 / p0 + (phi**2).sum() / r
    assert m == pytest.approx((m0 / p0 + (phi * y).sum() / r) / info, rel=1e-12)
    assert p == pytest.approx(1 / info, rel=1e-9)
    assert abs(m - 2014.0) < 10


def test_rls_forgets_and_keeps_its_floor():
    m, p = 1814.0, 1.0
    for _ in range(5000):
        m, p = A.rls_step(m, p, 1.0, 2000.0, 1.0, 0.99, 4.0, 100.0)
    assert p == 4.0 and m == pytest.approx(2000.0)  # the floor keeps it adapting


def test_split_keeps_the_axle_force_and_shares_small_forces_by_cornering_stiffness():
    cfg = A.AdaptiveConfig()
    fz = np.array([[3000.0, 7000.0, 2500.0, 5000.0], [6000.0, 4000.0, 4000.0, 4000.0]])
    axle = np.array([[1.0, -1.0], [4000.0, 2500.0]])
    fy = A.load_sensitive_split(axle, fz, cfg)
    assert np.allclose(fy[:, :2].sum(1), 2 * axle[:, 0]) and np.allclose(fy[:, 2:].sum(1), 2 * axle[:, 1])
    a3, a4, a5 = cfg.tyre_a[3:6]
    bcd = lambda z: a3 * math.sin(a4 * math.atan(a5 * z * 1e-3 / cfg.tyre_fz_scale))  # noqa: E731
    # the table's first segment (0.25 deg) is the cornering stiffness to within the curve's bend
    assert fy[0, 0] / fy[0, 1] == pytest.approx(bcd(3000) / bcd(7000), rel=5e-3)
    assert fy[0, 2] / fy[0, 3] == pytest.approx(bcd(2500) / bcd(5000), rel=5e-3)
    assert fy[1, 2] == pytest.approx(fy[1, 3])
    # near the pair's peak the share approaches that of the friction limits D(Fz) = a1 Fz^2 + a2 Fz
    big = A.load_sensitive_split(np.array([[6500.0, 0.0]]), fz[:1], cfg)
    d = lambda z: cfg.tyre_a[1] * (z * 1e-3 / 1.75) ** 2 + cfg.tyre_a[2] * z * 1e-3 / 1.75  # noqa: E731
    assert abs(big[0, 0] / big[0, 1] - d(3000) / d(7000)) < 0.5 * abs(fy[0, 0] / fy[0, 1] - d(3000) / d(7000))


def pct(sc):
    truth, dec, runs = tr.simulate(sc, variants=(tf.SKFMEC, A.ADAPTIVE))
    m = tr.evaluate(truth, runs)
    true = tf.SkfConfig.default().m + sc.mass_delta_kg
    return m["variants"][A.ADAPTIVE], m["variants"][tf.SKFMEC], true, runs[A.ADAPTIVE]


def test_paper_scenario_within_seven_percent_and_the_mass_within_five():
    """+200 kg, mu 1.1 -> 0.2: per tyre <= 7 % of peak (SKFMEC 12.0 / 3.3 / 12.7 / 4.0), axles <= 5 %;
    DEGRADED until the mass estimate has converged (the ride heights' first update after 0.2 s of them)."""
    a, base, true, run = pct(load_tireforce_scenario("chassis_paper_mu_drop"))
    print("\nSKFMEC-A", a["rms_pct"], "SKFMEC", base["rms_pct"], "mass", a["mass"])
    assert all(a["rms_pct"][w] <= 7.0 for w in tf.WHEELS)
    assert a["rms_pct"]["front"] <= 5.0 and a["rms_pct"]["rear"] <= 5.0
    assert abs(a["mass"]["final_kg"] / true - 1) <= 0.05
    assert 0.2 < a["mass"]["converged_s"] < 0.22
    assert np.all(run.health[:400] != A.H_OK) and np.all(run.health[440:] == A.H_OK)
    for w in ("FR", "RR", "front", "rear"):  # no regression where the SKFMEC is good
        assert a["rms_pct"][w] <= base["rms_pct"][w] + 0.5


def test_relation_run_within_eight_percent():
    """70 km/h, steer 0 -> 4 deg (to 0.73 g), nominal mass, no longitudinal excitation: the ride heights
    find the (nominal) mass in cornering up to 0.73 g, the split brings RL from 12.5 % to under 8 %."""
    a, base, true, run = pct(load_tireforce_scenario("chassis_relation_70kph"))
    assert all(a["rms_pct"][w] <= 8.0 for w in tf.WHEELS)
    assert 0.2 < a["mass"]["converged_s"] < 0.22 and abs(run.mass[440:] / true - 1).max() <= 0.01
    # no wheel slips: the sides stay at the nominal; the road's friction from the kinematic coupling
    # reads no false low mu on this dry road (mu 1.1) up to 0.73 g
    assert run.mu.min() >= 0.98 and run.road_mu.min() >= 0.98
    for w in ("FR", "RR", "front", "rear"):
        assert a["rms_pct"][w] <= base["rms_pct"][w] + 0.5


def test_without_ride_heights_the_balance_alone():
    """A car without ride-height sensors ([sensors] ride_height = false: no CHS_RideHeight at all) is
    SKFMEC-A on the longitudinal balance alone, step for step the run with the ride heights ignored:
    on the relation run (no longitudinal excitation) the mass stays at the model's, DEGRADED."""
    from vehest_can.schema import read_toml
    from vehest_can.systems.tireforce.scenario import tireforce_scenario_from_dict, tireforce_scenario_path

    path = tireforce_scenario_path("chassis_relation_70kph")
    doc = read_toml(path)
    doc.setdefault("sensors", {})["ride_height"] = False
    _, dec, runs = tr.simulate(tireforce_scenario_from_dict(doc, path), variants=(A.ADAPTIVE,))
    assert dec.ride is None
    _, dec_r, _ = tr.simulate(load_tireforce_scenario("chassis_relation_70kph"), variants=())
    ignored = A.AdaptiveSkfmec().with_options(ride=False, transfer=False).run(dec_r.for_filter(), dec_r.mask, dec_r.ride)
    run = runs[A.ADAPTIVE]
    assert np.array_equal(run.fy, ignored.fy) and np.array_equal(run.mass, ignored.mass)
    assert np.all(run.mass == tf.SkfConfig.default().m) and np.all(run.health[400:] == A.H_DEGRADED)


def test_ride_heights_lost_hold_the_mass_and_resume():
    """Ride heights unusable for 2 s in the middle (NaN rows: timed out or a channel invalid) on the
    +200 kg paper run: the estimate holds (the braking balance alone moves it), then the ride
    heights come back and need 0.2 s before they update again; never a NaN."""
    _, dec, _ = tr.simulate(load_tireforce_scenario("chassis_paper_mu_drop"), variants=())
    ride = dec.ride.copy()
    ride[6000:10000] = np.nan
    u = dec.for_filter()
    for run in (A.AdaptiveSkfmec().run(u, dec.mask, ride), A.AdaptiveFixed().run(u, dec.mask, ride)):
        assert np.all(np.isfinite(run.mass)) and np.all(np.isfinite(run.fy))
        assert abs(run.mass[-1] / 2014.0 - 1) < 0.01
    with pytest.raises(Exception, match="shape"):
        A.AdaptiveSkfmec().run(u, dec.mask, ride[:10])


@pytest.mark.parametrize("delta", [-100.0, 0.0, 200.0, 400.0])
def test_ride_height_mass_from_the_springs_alone(delta):
    """The ride-height measurement itself against the plant: on a steady corner (60 km/h, 3 deg, the
    power-on run before its drive, no longitudinal excitation at all), sum k_i s_i + the links'
    vertical forces over g plus the unsprung mass is the car's mass within 1 %, for payloads
    -100 ... +400 kg, and SKFMEC-A's estimate within 2 % from 0.22 s on."""
    from vehest_can.schema import read_toml
    from vehest_can.systems.tireforce.scenario import tireforce_scenario_from_dict

    path = STRESS / "stress_power_on_cornering.toml"
    doc = read_toml(path)
    doc["vehicle"]["mass_delta_kg"] = delta
    doc["duration_s"] = 4.0
    sc = tireforce_scenario_from_dict(doc, path)
    truth, dec, runs = tr.simulate(sc, variants=(tf.SKFMEC, A.ADAPTIVE))
    cfg, skf = A.AdaptiveConfig(), tf.SkfConfig.default()
    k = np.array([cfg.spring_front] * 2 + [cfg.spring_rear] * 2)
    fy = truth["fy"]
    w = dec.ride @ k + skf.hf / skf.tf * (fy[:, 1] - fy[:, 0]) + skf.hr / skf.tr * (fy[:, 3] - fy[:, 2])
    m = w / skf.g + (skf.m - skf.ms)
    true = skf.m + delta
    ok = np.all(np.isfinite(dec.ride), axis=1)
    assert ok[2:].all()
    assert abs(np.nanmean(m[ok]) / true - 1) < 0.01
    mass = runs[A.ADAPTIVE].mass
    assert np.abs(mass[440:] / true - 1).max() < 0.02, (mass[440:].min(), mass[440:].max(), true)


_SLOW = pytest.mark.slow  # the quick tier keeps the first of each list; make test runs them all


@pytest.mark.parametrize("name", ["stress_highway_step_payload", *(pytest.param(n, marks=_SLOW) for n in (
    "stress_payload_p400kg", "stress_payload_m100kg", "stress_step_steer_p400kg_no_excitation",
    "stress_sine_steer_m100kg_no_excitation", "stress_split_mu_outer_low_p300", "stress_step_steer_4deg_p400"))])
def test_stress_within_ten_percent_and_the_mass_within_five(name):
    a, base, true, _ = pct(load_tireforce_scenario(STRESS / f"{name}.toml"))
    assert all(a["rms_pct"][w] <= 10.0 for w in tf.WHEELS), a["rms_pct"]
    assert abs(a["mass"]["final_kg"] / true - 1) <= 0.05


def test_split_mu_braking_within_ten_percent():
    """Left 1.0, right 0.3: the per-side friction estimate finds the right side's friction from its
    excess differential slip (the left stays at the nominal), and the split that uses it and the
    friction ellipse brings every tyre under 10 % (without them: 7.3 / 9.3 / 12.2 / 12.7 %)."""
    a, base, _, run = pct(load_tireforce_scenario(STRESS / "stress_split_mu_braking.toml"))
    print("\nSKFMEC-A", a["rms_pct"], "SKFMEC", base["rms_pct"])
    assert all(a["rms_pct"][w] <= 10.0 for w in tf.WHEELS), a["rms_pct"]
    braking = slice(int(2.5 / 5e-4), int(5.0 / 5e-4))
    assert np.all(run.mu[braking, 0] >= 0.95) and np.all(run.mu[braking, 2] >= 0.95)   # left: 1.0
    assert np.all(np.abs(run.mu[braking, 1] - 0.3) <= 0.1) and np.array_equal(run.mu[:, 1], run.mu[:, 3])
    assert np.all(run.mu[:int(1.0 / 5e-4)] == 1.0)  # no braking yet: not observable, the nominal


def test_braking_in_a_turn_at_the_limit_is_not_a_split():
    """Uniform mu 0.63 at the limit of a turn, then braking (a design case of the gate): both tyres of an axle
    slip beyond their linear slip, the lighter inner one more, and without the gate (the other tyre must be
    linear) the inner side was taken for a split at 0.26 and the inner tyres were 25 % off. With it no side is
    told from the other while braking, every tyre is within 10 %, and the fixed point follows the double."""
    sc = load_tireforce_scenario(STRESS / "stress_brake_in_turn_limit_p300.toml")
    a, base, _, run = pct(sc)
    print("\nSKFMEC-A", a["rms_pct"], "SKFMEC", base["rms_pct"])
    assert all(a["rms_pct"][w] <= 10.0 for w in tf.WHEELS), a["rms_pct"]
    braking = slice(int(3.2 / 5e-4), int(6.0 / 5e-4))
    assert np.array_equal(run.mu[braking, 0], run.mu[braking, 1])
    truth, dec, _ = tr.simulate(sc, variants=())
    u = dec.for_filter()
    fix = A.AdaptiveFixed().run(u, dec.mask, dec.ride)
    diff = 100 * np.sqrt(((fix.fy - run.fy)[truth["t"] >= 0.2] ** 2).mean(0)) / np.abs(truth["fy"]).max(0)
    assert np.all(diff <= 0.5) and fix.saturations == 0, diff


@pytest.mark.xfail(strict=True, reason="known shortfall: split-mu with the low side (0.3) inside a left curve, +100 kg: "
                   "FL 10.4 % (SKFMEC 10.7 %); the inner tyre saturates on mu 0.3 before the brake at 1 s, where no "
                   "slip shows it, and the friction estimate needs ~1 s to settle after it")
def test_split_mu_inner_low_within_ten_percent():
    a, _, _, _ = pct(load_tireforce_scenario(STRESS / "stress_split_mu_inner_low_p100.toml"))
    assert all(a["rms_pct"][w] <= 10.0 for w in tf.WHEELS), a["rms_pct"]


def test_low_mu_corner_within_ten_percent():
    """A steady corner at the limit of a mu 0.5 road, +200 kg (a probe written after the design): no
    wheel slips, so only the road's friction from the kinematic coupling (item 9) says mu is not 1; it
    reads 0.5 +- 0.1 from 2.5 s, and the inner FL goes from 13.3 % (without it; SKFMEC 10.0 %) to 5.0 %."""
    a, base, true, run = pct(load_tireforce_scenario(STRESS / "stress_low_mu_corner_p200.toml"))
    print("\nSKFMEC-A", a["rms_pct"], "SKFMEC", base["rms_pct"])
    assert all(a["rms_pct"][w] <= 10.0 for w in tf.WHEELS), a["rms_pct"]
    assert abs(a["mass"]["final_kg"] / true - 1) <= 0.05
    for w in ("FR", "RR", "front", "rear"):
        assert a["rms_pct"][w] <= base["rms_pct"][w] + 0.5
    assert np.all(np.abs(run.road_mu[int(2.5 / 5e-4):] - 0.5) <= 0.1)
    assert np.all(run.road_mu[:int(1.0 / 5e-4)] == 1.0)  # straight ahead: not observable, the nominal


def test_kinematic_coupling_and_its_model_against_the_plant():
    """Item 9's measurement and model against the 14-DOF plant's own slip angles (its truth): delta - L r / v_x
    is the plant's mean front minus mean rear slip angle, and the split's alpha_f - alpha_r from the true
    forces and loads is it at the true friction (mu 0.5), and 0.15-0.2 deg off at mu 1, on the low-mu corner;
    on a dry road (mu 1) the model at mu 1 is it (and at mu 0.5 only 0.02-0.2 deg off: little to see there)."""
    cfg, skf = A.AdaptiveConfig(), tf.SkfConfig.default()
    tabs = A.friction_tables(cfg)
    for name, mu, other, apart in (("stress_low_mu_corner_p200", 0.5, 1.0, 0.12), ("stress_payload_p0kg", 1.0, 0.5, 0.0)):
        truth, _ = load_tireforce_scenario(STRESS / f"{name}.toml").run_with_frames(ffi, lib)
        for t in (5.0, 6.0, 7.5):
            T = truth[int(t / 5e-4)]
            true = np.degrees(T["alpha"][:2].mean() - T["alpha"][2:].mean())
            assert np.degrees(T["steer"] - (skf.lf + skf.lr) * T["r"] / T["vx"]) == pytest.approx(true, abs=0.005)
            model = [A.kinematic_model(np.array([[T["fyf"], T["fyr"]]]), T["fz"][None], T["fx"][None], m, tabs, cfg)[0]
                     for m in (mu, other)]
            assert model[0] == pytest.approx(true, abs=0.02), (name, t)
            assert abs(model[1] - true) >= apart, (name, t)


def test_road_friction_needs_a_free_rolling_axle():
    """v_x comes from an axle whose wheels neither brake nor drive (|Fx| <= 400 N): the rear's mean speed,
    else the front's over cos delta, else none; with every wheel braked (-250 Nm on the low-mu corner's
    inputs) no axle rolls free and the road's friction is never updated (the nominal throughout)."""
    rw, w, d = 0.3, np.array([60.0, 62.0, 61.0, 63.0]), 0.1
    assert A.free_rolling_speed(w, np.array([900.0, 900.0, 10.0, -10.0]), d, rw, 400.0) == pytest.approx(rw * 62.0)
    assert A.free_rolling_speed(w, np.array([0.0, 0.0, -800.0, -800.0]), d, rw, 400.0) == pytest.approx(
        rw * 61.0 / math.cos(d))
    assert A.free_rolling_speed(w, np.array([-500.0, 0.0, -800.0, 0.0]), d, rw, 400.0) is None
    sc = load_tireforce_scenario(STRESS / "stress_low_mu_corner_p200.toml")
    _, dec, _ = tr.simulate(sc, variants=())
    u = dec.for_filter()
    u.torque[:] = -250.0
    assert np.all(A.AdaptiveSkfmec().run(u, dec.mask, dec.ride).road_mu == 1.0)


def test_load_transfer_from_the_ride_heights_against_the_plant():
    """Item 10 against the 14-DOF plant's own tyre loads (its truth) in a 0.8 g corner with +400 kg
    (the 4 deg step): each axle's lateral load transfer from the truth's spring deflections and axle
    forces is the truth's (Fz_R - Fz_L)/2 within 3 %, and SKFMEC-A's loads from the decoded ride
    heights are within 100 N RMS of the truth from 2 s on (38-51 N; eq. 39's transfer: 115-324 N)."""
    cfg, skf = A.AdaptiveConfig(), tf.SkfConfig.default()
    sc = load_tireforce_scenario(STRESS / "stress_step_steer_4deg_p400.toml")
    truth, dec, runs = tr.simulate(sc, variants=(A.ADAPTIVE,))
    late = slice(int(2.0 / 5e-4), len(runs[A.ADAPTIVE].fz))
    axle = np.c_[truth["fy"][:, :2].mean(1), truth["fy"][:, 2:].mean(1)]
    fz = A.ride_transfer(truth["fz"], axle, truth["spring_defl"], skf, cfg)
    for i, j in ((0, 1), (2, 3)):
        want = (truth["fz"][late, j] - truth["fz"][late, i]) / 2
        got = (fz[late, j] - fz[late, i]) / 2
        assert np.all(np.abs(got - want) <= 0.03 * np.abs(want)), np.abs(got / want - 1).max()
    err = np.sqrt(((runs[A.ADAPTIVE].fz - truth["fz"][:len(runs[A.ADAPTIVE].fz)])[late] ** 2).mean(0))
    base = np.sqrt(((A.AdaptiveSkfmec().with_options(transfer=False).run(dec.for_filter(), dec.mask, dec.ride).fz
                     - truth["fz"][:len(runs[A.ADAPTIVE].fz)])[late] ** 2).mean(0))
    print("\nload RMS error [N] with the ride heights", err.round(0), "with eq. 39's transfer", base.round(0))
    assert np.all(err <= 100.0) and np.all(err < base) and base.max() > 300.0


def test_power_on_cornering_within_ten_percent():
    """400 Nm per front wheel out of a steady corner, +200 kg: the payload is unobservable to the
    longitudinal balance until the drive at 4 s; the ride heights give it from 0.2 s (without them RL
    was 10.8 %, SKFMEC 22.7 %)."""
    a, _, true, _ = pct(load_tireforce_scenario(STRESS / "stress_power_on_cornering.toml"))
    assert all(a["rms_pct"][w] <= 10.0 for w in tf.WHEELS), a["rms_pct"]
    assert abs(a["mass"]["final_kg"] / true - 1) <= 0.05 and a["mass"]["converged_s"] < 0.22


def test_friction_similarity_is_the_magic_formula_at_that_friction():
    """The split's curve at friction mu, mu F(alpha / mu) from the mu = 1 table, against the formula
    evaluated at that mu directly (D times mu, B over mu: Bakker et al.'s formula is exactly
    similar), through the split itself: one tyre unloaded, so the other carries the axle."""
    cfg = A.AdaptiveConfig()
    for mu in (0.3, 0.6):
        fz = np.array([[4000.0, 0.0, 4000.0, 0.0]])
        alpha = np.zeros((1, 2))
        want = A.lateral_force(np.array([2.0]), np.array([4000.0]), A.AdaptiveConfig(mu=mu))[0] / 2
        fy = A.load_sensitive_split(np.array([[want, want]]), fz, cfg, mu=np.full((1, 4), mu), alpha=alpha)
        assert fy[0, 0] == pytest.approx(2 * want) and fy[0, 1] == 0.0
        # the slip angle the split finds is the one where the formula at mu gives that force
        assert alpha[0, 0] == pytest.approx(2.0, abs=0.02)


def test_ellipse_and_nominal_friction_leave_the_split_as_before():
    cfg = A.AdaptiveConfig()
    fz = np.array([[3000.0, 7000.0, 2500.0, 5000.0]])
    axle = np.array([[2500.0, 1500.0]])
    old = A.load_sensitive_split(axle, fz, cfg)
    assert np.array_equal(A.load_sensitive_split(axle, fz, cfg, mu=np.ones((1, 4)), cap=np.ones((1, 4))), old)
    tabs = A.friction_tables(cfg)
    cap = A.ellipse(np.array([[0.0, -2000.0, 0.0, 0.0]]), fz, np.ones((1, 4)), tabs, cfg)
    assert cap[0, 0] == 1.0 and cap[0, 1] < 1.0
    braked = A.load_sensitive_split(axle, fz, cfg, cap=cap)
    assert braked[0, 1] < old[0, 1] and braked[0, :2].sum() == pytest.approx(2 * axle[0, 0])


def test_slip_observation_inverts_the_combined_slip_model():
    """The friction from the excess slip against the plant's own combined-slip tyre (vh_mftire.c,
    Bakker, Pacejka & Lidner 1989): at mu 0.3 and 0.5, a braked wheel's (kappa, alpha) gives a force
    Fx; the slip beyond Fx's linear slip must give back mu."""
    cfg = A.AdaptiveConfig()
    tabs = A.friction_tables(cfg)
    tyre = _plant_tyre()
    for mu in (0.3, 0.5):
        for kappa, alpha_deg in ((-0.01, 1.4), (-0.02, 0.8)):
            fx, _ = tyre(kappa, math.radians(alpha_deg), 6000.0, mu)
            k_lin = abs(fx) * float(A._at_load(tabs["compliance"], np.array(6000.0)))
            obs = A.slip_observation(abs(kappa) - k_lin, fx, 6000.0, alpha_deg, tabs, cfg)
            assert obs == pytest.approx(mu, rel=0.12), (mu, kappa, alpha_deg, obs)
    # in the linear range (nominal friction) nothing is observed
    fx, _ = tyre(-0.002, 0.0, 6000.0, 1.0)
    k_lin = abs(fx) * float(A._at_load(tabs["compliance"], np.array(6000.0)))
    assert A.slip_observation(max(0.0, 0.002 - k_lin), fx, 6000.0, 0.0, tabs, cfg) is None
    # the gate's reading of the other tyre: linear at rest and at a small slip on the nominal friction, not
    # on mu 0.3 at a slip angle near its peak
    assert A.linear_share(0.0, 6000.0, 0.0, 1.0, tabs) == 1.0
    assert A.linear_share(fx, 6000.0, 0.0, 1.0, tabs) >= cfg.q_gate
    assert A.linear_share(fx, 6000.0, 3.0, 0.3, tabs) < cfg.q_gate


# ---- fixed point (c_core/tireforce/vh_tfa.c) -------------------------------------------------

@pytest.mark.parametrize("name", ["chassis_paper_mu_drop", *(pytest.param(n, marks=_SLOW) for n in (
    "chassis_relation_70kph", "stress/stress_highway_step_payload", "stress/stress_split_mu_braking",
    "stress/stress_power_on_cornering", "stress/stress_low_mu_corner_p200", "stress/stress_step_steer_4deg_p400"))])
def test_fixed_point_matches_double(name):
    """Fixed vs double <= 0.5 % of peak per tyre (the issue's line), no saturation, the same health
    and the same mass to 0.1 kg; the same integers from a fresh instance (bit-exact)."""
    sc = load_tireforce_scenario(tireforce_scenario_dir() / f"{name}.toml")
    truth, dec, _ = tr.simulate(sc, variants=())
    u = dec.for_filter()
    dbl = A.AdaptiveSkfmec().run(u, dec.mask, dec.ride)
    fix = A.AdaptiveFixed().run(u, dec.mask, dec.ride)
    sel = truth["t"] >= truth["t"][0] + 0.2
    peak = np.abs(truth["fy"]).max(0)
    diff = 100 * np.sqrt(((fix.fy - dbl.fy)[sel] ** 2).mean(0)) / peak
    print(f"\n{name}: fixed - double, % of peak:", diff.round(4))
    assert np.all(diff <= 0.5) and fix.saturations == 0
    assert np.array_equal(fix.health, dbl.health)
    assert np.abs(fix.mass - dbl.mass).max() < 0.1
    again = A.AdaptiveFixed().run(u, dec.mask, dec.ride)
    assert np.array_equal(again.fy, fix.fy) and np.array_equal(again.mass, fix.mass)


def test_fixed_point_refuses_bad_constants():
    p = A.fixed_params(tf.SkfConfig.default(), A.AdaptiveConfig())
    a = ffi.new("vh_tfa_t *")
    assert lib.vh_tfa_init(a, p) == lib.VH_OK
    for field, bad in (("decim", 0), ("p_floor", 0), ("k_hi", p.k_lo), ("inv_forget", 2**29), ("kin_p0", 0),
                       ("kin_dh_max", 0), ("alpha_kin", 0), ("kin_dh_max", 1001 << lib.VH_TFA_FN)):
        q = ffi.new("vh_tfa_params_t *", p[0])
        setattr(q, field, bad)
        assert lib.vh_tfa_init(a, q) == lib.VH_EINVAL, field
    # a configuration the host refuses, and the double version with it: tyres softer in roll than k_phi,
    # a zero measurement noise, and a derivative bound whose 1 + H P H would not fit its format
    from vehest_can.errors import ConfigError
    from vehest_can.native import NativeError

    for bad in (dict(tyre_kz=1000.0), dict(kin_r_deg=0.0), dict(kin_dh_max=300.0)):
        with pytest.raises(NativeError, match="SKFMEC-A constants"):
            A.fixed_params(tf.SkfConfig.default(), A.AdaptiveConfig(**bad))
        with pytest.raises(NativeError, match="SKFMEC-A constants"):
            A.AdaptiveSkfmec(adaptive=A.AdaptiveConfig(**bad))
    with pytest.raises(ConfigError, match="softer in roll"):
        A.bar_rates(tf.SkfConfig.default(), A.AdaptiveConfig(tyre_kz=1000.0))


def test_nan_inputs_are_masked_not_used():
    """A non-finite sample is a masked step in both versions (DEGRADED, mass held), never a number."""
    sc = load_tireforce_scenario("chassis_paper_mu_drop")
    _, dec, _ = tr.simulate(sc, variants=())
    u = dec.for_filter()
    u.ax[8000:8100] = np.nan
    for run in (A.AdaptiveSkfmec().run(u, dec.mask), A.AdaptiveFixed().run(u, dec.mask)):
        assert np.all(np.isfinite(run.fy)) and np.all(np.isfinite(run.mass))
        assert np.all(run.health[8000:8100] == A.H_DEGRADED)
        assert np.all(run.mass[8000:8100] == run.mass[7999])


def _plant_tyre():
    """The plant's combined-slip tyre (vh_mftire.c) with the car's size factor: (kappa, alpha, Fz, mu) -> (Fx, Fy)."""
    c = ffi.new("vh_mft_coef_t *")
    lib.vh_mft_coef_default(c)
    c.fz_scale = A.AdaptiveConfig().tyre_fz_scale
    fx, fy = ffi.new("double *"), ffi.new("double *")

    def tyre(kappa, alpha, fz, mu):
        lib.vh_mft_eval(c, fz, mu, kappa, math.tan(alpha), fx, fy)
        return fx[0], fy[0]
    return tyre


@pytest.mark.slow
def test_ablation_cli_prints_the_docs_table_and_refuses_a_bad_scenario(capsys, tmp_path):
    """`vehest-can study tireforce.ablation --markdown NAME`: the header and one row per
    scenario with every variant's cells; a missing or malformed scenario is a one-line error, rc 1."""
    from vehest_can.cli import main
    from vehest_can.systems.tireforce import ablation

    assert main(["study", "tireforce.ablation", "--markdown", "chassis_relation_70kph"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 3 and lines[2].startswith("| `chassis_relation_70kph` |")
    assert lines[0].count("|") == lines[2].count("|") == len(ablation.ABLATIONS) + 3
    bad = tmp_path / "bad.toml"
    bad.write_text("kind = 'tireforce'\nduration_s = 'long'\n")
    for arg in (str(tmp_path / "missing.toml"), str(bad)):
        assert main(["study", "tireforce.ablation", arg]) == 1
        err = capsys.readouterr().err
        assert err.startswith("error: ") and "Traceback" not in err and len(err.splitlines()) == 1


def test_a_spinning_car_is_not_ok():
    """Trail braking into a 5 deg step at 100 km/h (+100 kg): the plant's car spins (sideslip to 83 deg,
    v_x through zero). SKFMEC-A's health is never OK while the sideslip is above 3 deg or the car below
    5 m/s (the body's sideways sliding a_y - r v past 4 m/s^2, then the locked wheels), in double and in
    fixed point alike; on every shipped and stress run it stays OK (the tests above: |a_y - r v| <= 2.7).
    The paper's SKFMEC, the baseline as printed, has no such check and reports OK throughout."""
    from vehest_can.systems.tireforce.scenario import tireforce_scenario_from_dict

    doc = {"kind": "tireforce", "name": "spin_probe", "duration_s": 6.0, "seed": 31, "initial_speed_kmh": 100.0,
           "driver": {"steer_deg": [[0, 0], [1.0, 0], [1.3, 5.0]],
                      "brake_nm": [[0, 0, 0, 0, 0], [1.2, 0, 0, 0, 0], [1.5, 900, 900, 700, 700]]},
           "road": {"mu": [[0.0, 1.0]]}, "vehicle": {"mass_delta_kg": 100.0}}
    sc = tireforce_scenario_from_dict(doc, STRESS / "spin_probe.toml")
    truth, dec, runs = tr.simulate(sc, variants=(tf.SKFMEC, A.ADAPTIVE))
    run = runs[A.ADAPTIVE]
    n = len(run.health)
    beta = np.degrees(np.arctan2(np.abs(truth["vy"][:n]), np.abs(truth["vx"][:n])))
    assert beta.max() > 80.0 and truth["vx"][:n].min() < 0.0  # it does spin
    ok = run.health == A.H_OK
    assert ok[:int(1.3 / 5e-4)].mean() > 0.8  # OK before (once the mass has converged)
    assert not np.any(ok & ((beta > 3.0) | (np.abs(truth["vx"][:n]) < 5.0)))
    fixed = A.AdaptiveFixed().run(dec.for_filter(), dec.mask, dec.ride)
    assert np.array_equal(fixed.health, run.health)
    assert np.all(runs[tf.SKFMEC].health[int(1.0 / 5e-4):] == A.H_OK)
