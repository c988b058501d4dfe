"""The roll system in campaigns (issue 14): each run the closed loop in-process (plant, nodes, the
ECU's float32 UKF + SMC), its figures against the plant's truth; the shipped small campaign runs."""
from dataclasses import replace

import numpy as np

from vehest_can.campaign import Store, execute, load_campaign, summarize
from vehest_can.paths import shipped_dir, shipped_file
from vehest_can.systems import registered
from vehest_can.systems.roll.campaign import CAMPAIGN
from vehest_can.systems.roll.scenario import load_roll_scenario


def shipped(name):
    return load_campaign(shipped_file(name, shipped_dir("campaigns", "firmware_sim/campaigns", "*.toml")))


def test_registered_and_a_run_is_the_bus_loop_figures():
    assert next(s for s in registered() if s.name == "roll").campaign is CAMPAIGN
    sc = load_roll_scenario("roll_paper_36kph_active")
    m = CAMPAIGN.run(replace(sc, chassis=replace(sc.chassis, duration_s=2.0)))
    assert m["estimates"] == 196 and m["ukf_resets"] == 0 and m["limits_respected"] == 1.0
    assert 0 < m["ukf_roll_rms_pct_of_peak"] < 5 and 0 < m["ukf_roll_rate_rms_pct_of_peak"] < 10
    assert m["moment_peak_nm"]["front"] > 0 and np.isfinite(m["peak_ay_m_s2"])


def test_shipped_roll_campaign_runs(tmp_path):
    c = shipped("roll_small")
    assert c.runs >= 12 and shipped("roll_spread").runs >= 100
    c = replace(c, runs=3)
    counts = execute(c, Store(tmp_path, c), workers=1)
    assert counts["ran"] == 3 and counts["failed"] == 0
    s = summarize(c, Store(tmp_path, c).table())
    assert [a["passed"] for a in s["acceptance"]][2] == 3      # limits respected in every run
    for key in ("ukf_roll_rms_pct_of_peak", "ukf_roll_rate_rms_pct_of_peak"):
        assert s["metrics"][key]["no_value"] == 0 and s["metrics"][key]["worst"] > 0


def test_the_demo_reads_the_roll_acceptance_as_the_table_shows_it():
    """The demo's acceptance summary (and --check, --junit) reads what the roll table shows: a
    line that passes in the table passes there (it once read every roll line as FAIL)."""
    from vehest_can.sim.report import checks_of
    from vehest_can.systems.roll import report

    m = {"ukf_roll_rms_pct_of_peak": 0.3, "ukf_roll_rms_deg": 0.006, "peak_roll_deg": 2.0,
         "ukf_roll_rate_rms_pct_of_peak": 12.0, "ukf_roll_rate_rms_deg_s": 0.6, "peak_roll_rate_deg_s": 5.0,
         "steady_turn_rate_bias_deg_s": 0.05, "limits_respected": True, "speed_kmh": 72.0,
         "vs_passive": {"peak_roll_reduction_pct": 58.7}}
    table = report.acceptance(m)
    checks = checks_of({"acceptance": report.acceptance_entries(m)}, "roll.x")
    assert [c["passed"] for c in checks] == [ok for _, _, ok in table] == [True, False, True, True, True]
    assert [c["detail"] for c in checks] == [fig for _, fig, _ in table]
