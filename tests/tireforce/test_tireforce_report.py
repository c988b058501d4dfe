"""Tire-force report (vehest_can.systems.tireforce.report): seed 000's estimators against the 14-DOF plant.

* evaluate() on constructed runs with known answers (zero error, constant bias, axle scale, a split
  error the oracle must see, the settling window, the acceptance verdicts);
* decode_inputs / decode_signals: values encoded with cantools come back within half a LSB; SNA, a
  cleared qualifier and a wrong E2E CRC become NaN with their mask bits cleared, never numbers;
* on the plant (chassis_paper_mu_drop, +200 kg): fixed vs double <= 0.5 % of peak per tire with no
  saturation; SKFMEC within 10 % on the outer tires and both axles; the nominal car (mass_delta 0)
  within 10 % on all four tires; the inner-tire shortfall is a strict xfail that records its
  figures; the oracle split alone exceeds 5 % on the inner front tire (relation 2 under the plant's
  load-sensitive tyres);
* plots and the command line write non-empty files.
"""
import json

import numpy as np
import pytest
from frames_oracle import E2ESender

from vehest_can.errors import ConfigError
from vehest_can.native import lib
from vehest_can.systems.tireforce import api as tf
from vehest_can.systems.tireforce import report as tr

DT = 5e-4
FIXED_TARGET = tr.TARGET_FIXED_PCT
TIRE_TARGET = tr.TARGET_TIRE_PCT


# ---- constructed truth: known answers --------------------------------------------------------

def constructed_truth(n=2000, d=0.0):
    """A drive whose per-tire forces are split exactly by the load shares (plus +-d on the front
    pair at equal loads when d != 0: the oracle split then errs by exactly d on both front tires)."""
    t = np.arange(n) * DT
    s = np.sin(2 * np.pi * t)
    fz = np.c_[5000 - 800 * s, 5000 + 800 * s, 3500 - 500 * s, 3500 + 500 * s]
    axle = np.c_[2000 * s, 1500 * s]
    fy = np.empty((n, 4))
    for i in range(4):                                   # F_yi = 2 F_y,axle F_zi / (F_z,in + F_z,out)
        a = i // 2
        fy[:, i] = 2 * axle[:, a] * fz[:, i] / (fz[:, 2 * a] + fz[:, 2 * a + 1])
    if d:
        fz[:, :2] = 5000.0
        fy[:, 0], fy[:, 1] = axle[:, 0] - d, axle[:, 0] + d
    return {"t": t, "fy": fy, "fz": fz}


def run_of(fy, saturations=0, resets=0):
    n = len(fy)
    return tf.TireForceRun(x=np.zeros((n, 7)), fy=np.asarray(fy, float), fz=np.zeros((n, 4)),
                           health=np.full(n, lib.VH_HEALTH_OK, np.uint8), resets=resets, saturations=saturations)


def test_evaluate_perfect_runs_have_zero_error_and_pass():
    truth = constructed_truth()
    m = tr.evaluate(truth, {v: run_of(truth["fy"]) for v in tf.VARIANTS})
    for v in tf.VARIANTS:
        assert all(x == 0.0 for x in m["variants"][v]["rms_pct"].values())
        assert m["variants"][v]["axle_scale_pct"] == {"front": 0.0, "rear": 0.0}
        assert m["variants"][v]["health"]["OK"] == len(truth["t"])
    assert max(m["oracle"]["split_pct"].values()) < 1e-12
    assert all(x == 0.0 for x in m["fixed_vs_double"]["rms_pct"].values())
    verdicts = {a["line"]: a["verdict"] for a in m["acceptance"]}
    assert [v for k, v in verdicts.items() if "per-tire" in k] == ["pass", "pass"]
    assert verdicts[next(k for k in verdicts if k.startswith("fixed vs double"))] == "pass"
    # equal, not better: "SKFMEC better than the EKF" is not claimed
    assert verdicts[next(k for k in verdicts if k.startswith("SKFMEC"))] == "SHORT"


def test_evaluate_constant_bias_gives_known_rms_and_settling_is_excluded():
    truth = constructed_truth()
    fy, peak = truth["fy"], np.abs(truth["fy"]).max(axis=0)
    bias = np.array([100.0, -50.0, 30.0, 0.0])
    est = fy + bias
    k0 = int(round(0.2 / DT))
    est[:k0] += 1e5                       # the settling window: must not count
    m = tr.evaluate(truth, {tf.SKFMEC: run_of(est)}, settle_s=0.2)
    vm = m["variants"][tf.SKFMEC]
    assert m["samples"] == len(fy) - k0
    for i, w in enumerate(tr.WHEELS):
        assert vm["rms_N"][w] == pytest.approx(abs(bias[i]), abs=1e-9)
        assert vm["rms_pct"][w] == pytest.approx(100 * abs(bias[i]) / peak[i], abs=1e-9)
        assert vm["mean_error_N"][w] == pytest.approx(bias[i], abs=1e-9)
    assert vm["rms_N"]["front"] == pytest.approx(25.0, abs=1e-9)   # (100 - 50) / 2
    assert vm["rms_N"]["rear"] == pytest.approx(15.0, abs=1e-9)
    with pytest.raises(ConfigError):
        tr.evaluate(truth, {tf.SKFMEC: run_of(est)}, settle_s=10.0)


def test_evaluate_axle_scale_fixed_vs_double_and_verdicts():
    truth = constructed_truth()
    fy, peak = truth["fy"], np.abs(truth["fy"]).max(axis=0)
    low = 0.9 * fy                                       # axle forces 10 % low, shares right
    off = fy + 0.01 * peak                               # 1 % of peak away from the double run
    m = tr.evaluate(truth, {tf.SKFMEC: run_of(fy), tf.FIXED: run_of(off, saturations=3), tf.EKF: run_of(low)})
    assert m["variants"][tf.EKF]["axle_scale_pct"]["front"] == pytest.approx(-10.0, abs=1e-9)
    assert m["variants"][tf.EKF]["axle_scale_pct"]["rear"] == pytest.approx(-10.0, abs=1e-9)
    # the estimated axle forces split by the true shares are the estimate itself here
    for w in tr.WHEELS:
        assert m["variants"][tf.EKF]["axle_only_pct"][w] == pytest.approx(m["variants"][tf.EKF]["rms_pct"][w])
        assert m["fixed_vs_double"]["rms_pct"][w] == pytest.approx(1.0, abs=1e-9)
    assert m["fixed_vs_double"]["saturations"] == 3
    verdict = {a["line"].split(" ")[0]: a for a in m["acceptance"]}
    assert verdict["fixed"]["verdict"] == "SHORT"
    assert verdict["SKFMEC"]["verdict"] == "pass"                  # SKFMEC 0 % < EKF on every tire
    text = tr.table({**m, "scenario": "constructed"})
    assert "[FAIL] fixed vs double" in text and "[PASS] SKFMEC" in text and "(!: a tyre over the" in text


def test_evaluate_ay_band_keeps_only_samples_within_it():
    truth = constructed_truth()
    n = len(truth["t"])
    truth["ay"] = np.where(np.arange(n) < n // 2, 2.0, 6.0)      # 0.20 g, then 0.61 g
    peak_low = np.abs(truth["fy"][: n // 2]).max(axis=0)
    est = truth["fy"] + 10.0
    est[n // 2:] += 1e4                                          # only above the band
    m = tr.evaluate(truth, {tf.SKFMEC: run_of(est)}, max_ay_g=0.5)
    assert m["samples"] == n // 2 - int(round(0.2 / DT)) and m["max_ay_g"] == 0.5
    for i, w in enumerate(tr.WHEELS):
        assert m["variants"][tf.SKFMEC]["rms_pct"][w] == pytest.approx(1000.0 / peak_low[i])
    assert "|a_y| <= 0.5 g" in tr.table({**m, "scenario": "x"})
    assert tr.evaluate(truth, {tf.SKFMEC: run_of(est)})["variants"][tf.SKFMEC]["rms_N"]["FL"] > 1e3


def test_oracle_split_sees_a_known_split_error():
    d = 120.0
    truth = constructed_truth(d=d)
    peak = np.abs(truth["fy"]).max(axis=0)
    m = tr.evaluate(truth, {tf.SKFMEC: run_of(truth["fy"])})
    assert m["oracle"]["split_pct"]["FL"] == pytest.approx(100 * d / peak[0], rel=1e-12)
    assert m["oracle"]["split_pct"]["FR"] == pytest.approx(100 * d / peak[1], rel=1e-12)
    assert m["oracle"]["split_pct"]["RL"] < 1e-12


def test_verdict_names_the_short_tires():
    truth = constructed_truth()
    peak = np.abs(truth["fy"]).max(axis=0)
    est = truth["fy"].copy()
    est[:, 0] += 0.15 * peak[0]                          # FL 15 % of peak off
    m = tr.evaluate(truth, {tf.SKFMEC: run_of(est)})
    (line,) = [a for a in m["acceptance"] if "per-tire" in a["line"]]
    assert line["verdict"] == "SHORT" and "FL 15.00 %" in line["detail"] and "FR" not in line["detail"]
    assert "FL" in tr.table({**m, "scenario": "x"}).split("\n")[1]
    assert "15.00!" in tr.table({**m, "scenario": "x"})


def test_relations_on_a_constructed_truth():
    truth = constructed_truth()
    n = len(truth["t"])
    ay = np.linspace(0.0, 0.6 * 9.81, n)
    phi = ay / 300.0
    axle = np.c_[110e3 * phi, 75e3 * phi]
    fz0 = np.array([5000.0, 5000.0, 3500.0, 3500.0])
    share = np.c_[1 - ay / 30, 1 + ay / 30]
    fz = np.c_[fz0[:2] * share, fz0[2:] * share]
    fz[0] = fz0                                          # static at the first sample
    half = np.c_[1 - ay / 60, 1 + ay / 60]                # front: half the load share's deviation
    fy = np.c_[axle[:, :1] * half, axle[:, 1:] * share]
    rel = tr.relations({"t": truth["t"], "fy": fy, "fz": fz, "phi": phi, "ay": ay})
    assert rel["zeta1"]["min"] == pytest.approx(110e3) and rel["zeta1"]["max"] == pytest.approx(110e3)
    assert rel["zeta2"]["spread_pct"] == pytest.approx(0.0, abs=1e-9)
    assert rel["share_FR"]["share_ratio_median"] == pytest.approx(0.5)   # half the load share
    assert rel["share_RR"]["share_ratio_median"] == pytest.approx(1.0)   # relation 2 exact


# ---- decoding --------------------------------------------------------------------------------

def _signals(rng):
    v = {"LongAccel": rng.uniform(-5, 5), "LatAccel": rng.uniform(-8, 8), "YawRate": rng.uniform(-1, 1),
         "RollRate": rng.uniform(-0.5, 0.5), "SteerAngle": rng.uniform(-0.3, 0.3)}
    for w in tf.WHEELS:
        v[f"WheelSpeed{w}"] = rng.uniform(0, 200)
        v[f"WheelTorque{w}"] = rng.uniform(-2000, 2000)
    v.update({f"Qf_{k}": 1 for k in list(v)})
    return v


def _frames(rows):
    tx = E2ESender("ch")
    return [tx.message("CHS_Sensors", r) for r in rows]


def test_decode_inputs_round_trips_cantools_encoding():
    rng = np.random.default_rng(5)
    rows = [_signals(rng) for _ in range(50)]
    dec = tr.decode_inputs(_frames(rows))
    assert len(dec) == 50 and dec.e2e_rejected == 0
    assert np.all(dec.mask == lib.VH_SKF_ALL_VALID) and not any(dec.invalid.values())
    msg = tr._chs_message()
    for sig, (field, col, _) in tr._INPUT_SIGNALS.items():
        got = getattr(dec.inputs, field)
        got = got if col is None else got[:, col]
        want = np.array([r[sig] for r in rows])
        assert np.max(np.abs(got - want)) <= msg.get_signal_by_name(sig).scale / 2 + 1e-12, sig
    # payload bytes give the same; messages of other IDs are skipped
    payloads = [bytes(m.data) for m in _frames(rows)]
    again = tr.decode_inputs(payloads)
    np.testing.assert_array_equal(again.inputs.matrix(), dec.inputs.matrix())
    other = _frames(rows[:1])[0]
    other.arbitration_id += 1
    assert len(tr.decode_inputs([other] + _frames(rows[:3]))) == 3


def test_decode_inputs_refuses_sna_invalid_qualifiers_and_bad_crc():
    rng = np.random.default_rng(6)
    rows = [_signals(rng) for _ in range(6)]
    rows[1]["YawRate"] = "SNA"                          # encoded as the raw SNA value by cantools
    rows[2]["Qf_LatAccel"] = 0                          # value present, qualifier INVALID
    rows[3]["WheelSpeedRL"] = "SNA"                     # an input: the whole input set goes
    rows[4]["Qf_WheelTorqueFR"] = 0
    frames = _frames(rows)
    data = bytearray(frames[5].data)
    data[4] ^= 0x01                                     # LatAccel bit flip: the CRC no longer matches
    frames[5].data = data
    dec = tr.decode_inputs(frames)
    m, u = dec.mask, dec.inputs
    assert m[0] == lib.VH_SKF_ALL_VALID
    assert np.isnan(u.r[1]) and m[1] == lib.VH_SKF_ALL_VALID & ~lib.VH_SKF_Y_R
    assert np.isnan(u.ay[2]) and m[2] == lib.VH_SKF_ALL_VALID & ~lib.VH_SKF_Y_AY
    assert np.isnan(u.omega[3, 2]) and m[3] == lib.VH_SKF_ALL_VALID & ~lib.VH_SKF_U_VALID
    assert np.isnan(u.torque[4, 1]) and m[4] == lib.VH_SKF_ALL_VALID & ~lib.VH_SKF_U_VALID
    assert np.all(np.isnan(u.matrix()[5])) and m[5] == 0 and dec.e2e_rejected == 1
    assert dec.invalid["YawRate"] == 1 and dec.invalid["LatAccel"] == 1 and dec.invalid["WheelSpeedRL"] == 1
    # the other values of a row with one invalid signal stay
    assert np.isfinite(u.ay[1]) and np.isfinite(u.omega[3, 0])
    # without the E2E check the corrupted frame decodes (to a wrong number): the check is what refuses it
    assert np.isfinite(tr.decode_inputs(frames, e2e=False).inputs.ay[5])
    # the filter input: NaN -> 0 only where the mask bit is clear; anything else is refused
    fin = dec.for_filter()
    assert np.all(np.isfinite(fin.matrix()))
    dec.mask[1] |= lib.VH_SKF_Y_R
    with pytest.raises(ConfigError):
        dec.for_filter()


def test_decode_signals_matches_decode_inputs():
    rng = np.random.default_rng(7)
    rows = [_signals(rng) for _ in range(5)]
    rows[2]["SteerAngle"] = "SNA"
    rows[3]["Qf_RollRate"] = 0
    frames = _frames(rows)
    msg = tr._chs_message()
    by_bytes = tr.decode_inputs(frames)
    for choices in (False, True):
        dicts = [msg.decode(bytes(f.data), decode_choices=choices) for f in frames]
        by_dict = tr.decode_signals(dicts)
        np.testing.assert_array_equal(by_dict.mask, by_bytes.mask)
        np.testing.assert_allclose(by_dict.inputs.matrix(), by_bytes.inputs.matrix(), rtol=0, atol=1e-12)
    with pytest.raises(ConfigError):
        tr.decode_signals([{"LongAccel": 0.0}])


def test_masked_rows_reach_the_filter_as_degraded_steps():
    """A decoded invalid sample is not used: the step is DEGRADED, never a number in the filter."""
    from vehest_can.native import ffi
    from vehest_can.systems.tireforce.scenario import load_tireforce_scenario

    sc = load_tireforce_scenario("chassis_paper_mu_drop")
    truth, frames = sc.run_with_frames(ffi, lib)
    payloads = [p for i, p in frames if i == 0x110][:2000]
    k = 1500
    bad = bytearray(payloads[k])
    bad[2] ^= 0xFF                                      # corrupt: E2E refuses the frame
    payloads[k] = bytes(bad)
    dec = tr.decode_inputs(payloads)
    runs = tr.run_estimators(dec, (tf.SKFMEC, tf.FIXED))
    for run in runs.values():
        assert run.health[k] == lib.VH_HEALTH_DEGRADED
        assert run.health[k + 1] == lib.VH_HEALTH_OK and run.resets == 0


# ---- against the plant -----------------------------------------------------------------------

@pytest.fixture(scope="module")
def paper():
    sc = tr.scenario("chassis_paper_mu_drop")
    assert sc.mass_delta_kg == 200.0
    truth, dec, runs = tr.simulate(sc)
    return truth, runs, tr.evaluate(truth, runs)


@pytest.fixture(scope="module")
def nominal():
    sc = tr.scenario("chassis_paper_mu_drop", mass_delta_kg=0.0)
    assert sc.mass_delta_kg == 0.0
    truth, dec, runs = tr.simulate(sc, (tf.SKFMEC, tf.FIXED))
    return tr.evaluate(truth, runs)


@pytest.fixture(scope="module")
def relation():
    truth, dec, runs = tr.simulate(tr.scenario("chassis_relation_70kph"))
    return truth, runs


@pytest.mark.slow
def test_plant_fixed_point_matches_double(paper):
    _, runs, m = paper
    fd = m["fixed_vs_double"]
    assert max(fd["rms_pct"].values()) <= FIXED_TARGET, fd
    assert fd["saturations"] == 0 and runs[tf.FIXED].resets == 0 and runs[tf.SKFMEC].resets == 0
    assert next(a for a in m["acceptance"] if a["line"].startswith("fixed"))["verdict"] == "pass"


@pytest.mark.slow
@pytest.mark.parametrize("variant", [tf.SKFMEC, tf.FIXED])
def test_plant_outer_tires_and_axles_within_target(paper, variant):
    pct = paper[2]["variants"][variant]["rms_pct"]
    for key in ("FR", "RR", "front", "rear"):
        assert pct[key] <= TIRE_TARGET, (key, pct)


@pytest.mark.slow
@pytest.mark.parametrize("variant", [tf.SKFMEC, tf.FIXED])
def test_plant_nominal_mass_all_tires_within_target(nominal, variant):
    pct = nominal["variants"][variant]["rms_pct"]
    assert all(pct[w] <= TIRE_TARGET for w in tr.WHEELS), pct


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="known shortfall: with the +200 kg mass error SKFMEC's inner tires "
                                       "(FL, RL) miss 10 % of peak; axle forces ~10 % low (invisible to the "
                                       "yaw-rate and a_y residuals) on top of relation 2's split error")
def test_plant_inner_tires_within_target_known_shortfall(paper, record_property):
    m = paper[2]
    pct = m["variants"][tf.SKFMEC]["rms_pct"]
    record_property("skfmec_rms_pct", pct)
    record_property("oracle_split_pct", m["oracle"]["split_pct"])
    record_property("axle_scale_pct", m["variants"][tf.SKFMEC]["axle_scale_pct"])
    assert pct["FL"] <= TIRE_TARGET and pct["RL"] <= TIRE_TARGET, (pct, m["oracle"]["split_pct"])


@pytest.mark.slow
def test_plant_oracle_split_alone_exceeds_five_percent_on_inner_front(paper):
    """Relation 2 under the plant's load-sensitive tyres: even the true axle forces split by the
    true loads miss the inner front tire by more than 5 % of its peak (a plant whose tyres were
    linear in load would bring this to ~0 and show here)."""
    split = paper[2]["oracle"]["split_pct"]
    assert split["FL"] > 5.0, split
    assert split["FL"] > split["FR"]


@pytest.mark.slow
def test_plant_relation_ramp_within_target_below_half_g(relation):
    """The relation-check ramp (0 -> 4 deg, true mass = model mass): within the paper's validity
    range (|a_y| <= 0.5 g) every tire is within 10 %; relation 1 holds within 5 % over 0.1-0.5 g."""
    truth, runs = relation
    m = tr.evaluate(truth, runs, max_ay_g=0.5)
    for v in (tf.SKFMEC, tf.FIXED):
        pct = m["variants"][v]["rms_pct"]
        assert all(pct[w] <= TIRE_TARGET for w in tr.WHEELS), (v, pct)
    rel = tr.relations(truth)
    assert rel["zeta1"]["spread_pct"] < 5.0 and rel["zeta2"]["spread_pct"] < 5.0, rel


@pytest.mark.slow
def test_plots_and_command_line_write_files(paper, relation, tmp_path, capsys):
    truth, runs, _ = paper
    files = tr.plots("forces", truth, runs, tmp_path / "f", title="paper")
    files += tr.plots("relations", relation[0], None, tmp_path / "r")
    assert {p.name for p in files} == {"fig5_inner_front.png", "fig6_outer_front.png", "error_per_tire.png",
                                        "fig3_zeta.png", "fig4_share.png", "mass.png", "friction.png"}
    for p in files:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 10_000
    with pytest.raises(ConfigError):
        tr.plots("nonsense", truth, runs, tmp_path)

    from vehest_can.cli import main

    assert main(["study", "tireforce.report", "chassis_relation_70kph", "-o", str(tmp_path / "cli")]) == 0
    out = capsys.readouterr().out
    assert "== chassis_relation_70kph" in out and "acceptance:" in out
    metrics = json.loads((tmp_path / "cli" / "metrics.json").read_text())
    assert metrics[0]["scenario"] == "chassis_relation_70kph"
    assert set(metrics[0]["variants"]) == set(tr.ALL_VARIANTS)
    assert len(metrics[0]["plots"]) == 7 and all((tmp_path / "cli").joinpath(p).exists() for p in metrics[0]["plots"])


def test_skfmec_a_acceptance_lines_judge_its_tyres_and_its_mass():
    """SKFMEC-A has its own lines: per-tyre against the 10 % target, and the final mass against the
    plant's within 5 %, only once converged; a run at the model's mass that never converged (no
    longitudinal excitation) has no mass line."""
    from vehest_can.systems.tireforce.adaptive import ADAPTIVE

    m0 = tf.SkfConfig.default().m
    pct = {"FL": 3.0, "FR": 2.0, "RL": 11.0, "RR": 2.5, "front": 2.0, "rear": 1.8}

    def lines(final_kg, converged_s, true_kg):
        v = {ADAPTIVE: {"rms_pct": pct, "axle_scale_pct": {"front": 0.0, "rear": 0.0},
                        "mass": {"final_kg": final_kg, "final_std_kg": 9.0, "converged_s": converged_s}}}
        m = {"variants": v, "oracle": {"split_pct": dict.fromkeys(tr.WHEELS, 1.0)}, "true_mass_kg": true_kg}
        return {a["line"]: a for a in tr.acceptance(m)}

    got = lines(m0 + 190, 1.5, m0 + 200)
    tyres = got[f"per-tire RMS <= 10 % of peak |Fy| ({ADAPTIVE})"]
    mass = got[f"mass estimate within 5 % of the truth ({ADAPTIVE})"]
    assert tyres["verdict"] == "SHORT" and "RL 11.00 %" in tyres["detail"]
    assert mass["verdict"] == "pass" and "converged at 1.50 s" in mass["detail"]
    assert lines(m0 + 400, 1.5, m0)[f"mass estimate within 5 % of the truth ({ADAPTIVE})"]["verdict"] == "SHORT"
    assert lines(m0, None, m0 + 200)[f"mass estimate within 5 % of the truth ({ADAPTIVE})"]["verdict"] == "SHORT"
    assert not any("mass" in k for k in lines(m0, None, m0))
