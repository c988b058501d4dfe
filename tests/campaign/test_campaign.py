"""Campaigns: the spec's checks, determinism on every executor, resume after SIGINT, failed runs
recorded, the worst run re-runs alone to the same metric."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from vehest_can.campaign import Store, execute, load_campaign, summarize, systems, write_run_scenario
from vehest_can.campaign.runner import flatten
from vehest_can.campaign.systems import system_for
from vehest_can.cli import main
from vehest_can.errors import ScenarioError

SHORT_DRIVELINE = """
[campaign]
name = "{name}"
base = "launch_2nd"
runs = {runs}
seed = 11
metrics = ["speeds+torque.*"]

[[vary]]
key = "duration_s"
dist = "list"
values = [{duration}]

[[vary]]
key = "initial_speed_kmh"
dist = "uniform"
low = 0
high = 30

[[vary]]
key = "sensors.shaft_torque_std_nm"
dist = "normal"
mean = 8.0
sd = 1.0

[[acceptance]]
metric = "speeds+torque.rms_est_minus_truth_nm"
max = 6.0
"""


def spec(tmp_path, text, name="c.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def short(tmp_path, runs=50, duration=1.5, name="short"):
    return spec(tmp_path, SHORT_DRIVELINE.format(name=name, runs=runs, duration=duration), f"{name}.toml")


def frame(store):
    """The result table without the wall-clock column, as plain lists (NaN == NaN: compared as JSON)."""
    t = store.table()
    return json.loads(json.dumps({c: t.column(c).to_pylist() for c in t.column_names if c != "wall_s"}),
                      parse_constant=str)


@pytest.mark.slow
def test_the_same_campaign_is_identical_on_one_and_two_workers_and_dask(tmp_path):
    pytest.importorskip("distributed")
    c = load_campaign(short(tmp_path))
    tables = {}
    for label, kw in (("1", {"workers": 1}), ("2", {"workers": 2}),
                      ("dask", {"workers": 2, "scheduler": "local-dask"})):
        store = Store(tmp_path / label, c)
        counts = execute(c, store, batch_size=3, **kw)
        assert counts["ran"] == 50 and counts["failed"] == 0
        tables[label] = frame(store)
    assert tables["1"]["run"] == list(range(50))
    assert tables["1"] == tables["2"] == tables["dask"]
    # the runs differ from each other: the parameters and seeds were really drawn per run
    assert len(set(tables["1"]["seed"])) == 50
    assert len(set(tables["1"]["param.initial_speed_kmh"])) == 50
    assert len(set(tables["1"]["metric.speeds+torque.rms_est_minus_truth_nm"])) > 40


def test_run_values_follow_the_distributions(tmp_path):
    c = load_campaign(short(tmp_path, runs=400))
    draws = np.array([[c.run_doc(i)[1]["initial_speed_kmh"], c.run_doc(i)[1]["sensors.shaft_torque_std_nm"]]
                      for i in range(400)])
    assert 0 <= draws[:, 0].min() and draws[:, 0].max() <= 30 and abs(draws[:, 0].mean() - 15) < 1.5
    assert abs(draws[:, 1].mean() - 8.0) < 0.2 and abs(draws[:, 1].std() - 1.0) < 0.15
    doc, values = c.run_doc(3)
    assert doc["initial_speed_kmh"] == values["initial_speed_kmh"] and doc["sensors"]["shaft_torque_std_nm"] == values[
        "sensors.shaft_torque_std_nm"]


def test_grid_is_the_cartesian_product(tmp_path):
    p = spec(tmp_path, """
[campaign]
base = "launch_2nd"
runs = 12
[[vary]]
key = "duration_s"
dist = "grid"
values = [0.5, 0.6]
[[vary]]
key = "initial_speed_kmh"
dist = "grid"
values = [0.0, 10.0, 20.0]
""")
    c = load_campaign(p)
    pts = [(c.run_doc(i)[1]["duration_s"], c.run_doc(i)[1]["initial_speed_kmh"]) for i in range(12)]
    assert sorted(set(pts)) == [(a, b) for a in (0.5, 0.6) for b in (0.0, 10.0, 20.0)]
    assert all(pts.count(p) == 2 for p in set(pts))


@pytest.mark.parametrize("text, problem", [
    ("[campaign]\nruns = 3\n", "campaign.base: missing (required)"),
    ("[campaign]\nbase = 'launch_2nd'\nruns = 0\n", "campaign.runs: must be an integer in [1, 1e+07], not 0"),
    ("[campaign]\nbase = 'launch_2nd'\nruns = 2\nspeed = 3\n", "campaign.speed: unknown key"),
    ("[campaign]\nbase = 'nosuch'\nruns = 2\n", "campaign.base: no scenario 'nosuch'"),
    ("[campaign]\nbase = 'launch_2nd'\nruns = 2\n[[vary]]\nkey = 'seed'\ndist = 'beta'\n",
     "vary[0].dist: must be one of uniform, normal, list, grid, not 'beta'"),
    ("[campaign]\nbase = 'launch_2nd'\nruns = 2\n[[vary]]\nkey = 'x'\ndist = 'uniform'\nlow = 1\n",
     "vary[0].high: missing"),
    ("[campaign]\nbase = 'launch_2nd'\nruns = 2\n[[vary]]\nkey = 'x'\ndist = 'uniform'\nlow = 1\nhigh = 0\n",
     "vary[0].high: must be above low (1), not 0"),
    ("[campaign]\nbase = 'launch_2nd'\nruns = 2\n[[vary]]\nkey = 'x'\ndist = 'normal'\nmean = nan\nsd = 1\n",
     "vary[0].mean: must be a finite number"),
    ("[campaign]\nbase = 'launch_2nd'\nruns = 3\n[[vary]]\nkey = 'seed'\ndist = 'grid'\nvalues = [1, 2]\n",
     "campaign.runs: 3 is not a multiple of the grid's 2 points"),
    ("[campaign]\nbase = 'launch_2nd'\nruns = 2\n[[vary]]\nkey = 'initial_speed_kmh'\ndist = 'list'\nvalues = [999]\n",
     "run 0 of this campaign is not a valid scenario"),
    ("[campaign]\nbase = 'launch_2nd'\nruns = 2\n[[vary]]\nkey = 'driver.nosuch'\ndist = 'list'\nvalues = [1]\n",
     "driver.nosuch: unknown key"),
    ("[campaign]\nbase = 'launch_2nd'\nruns = 2\n[[acceptance]]\nmetric = 'x'\n", "acceptance[0]: needs min, max or both"),
    ("[campaign\n", "(TOML syntax)"),
])
def test_bad_campaign_files_are_clear_errors(tmp_path, text, problem):
    with pytest.raises(ScenarioError) as err:
        load_campaign(spec(tmp_path, text))
    assert problem in str(err.value)


def test_a_run_that_raises_is_a_failed_row_not_a_lost_campaign(tmp_path):
    # run 1 is out of the scenario loader's range: refused when the run starts, a failed row
    p = spec(tmp_path, """
[campaign]
base = "chassis_relation_70kph"
runs = 2
[[vary]]
key = "vehicle.mass_delta_kg"
dist = "grid"
values = [0.0, -4000.0]
[[vary]]
key = "duration_s"
dist = "list"
values = [0.5]
""")
    c = load_campaign(p)
    store = Store(tmp_path / "out", c)
    counts = execute(c, store, workers=1)
    assert counts == {"runs": 2, "already_done": 0, "ran": 2, "failed": 1}
    t = frame(store)
    assert t["error"][0] is None and "vehicle.mass_delta_kg: -4000.0 is out of range" in t["error"][1]
    s = summarize(c, store.table())
    assert s["failed"] == 1 and s["failures"][0]["run"] == 1


def test_results_of_another_campaign_are_not_mixed(tmp_path):
    a = load_campaign(short(tmp_path, runs=4))
    execute(a, Store(tmp_path / "out", a), workers=1)
    b = load_campaign(short(tmp_path, runs=5))
    with pytest.raises(Exception, match="results of another campaign"):
        execute(b, Store(tmp_path / "out", b), workers=1)
    assert execute(b, Store(tmp_path / "out", b), workers=1, fresh=True)["ran"] == 5


def _sigint_default() -> None:
    """In the child: SIGINT back to its default. A shell that started the suite in the background
    (no job control) ignores SIGINT, children inherit that, and Python keeps an ignored SIGINT
    ignored: the campaign would run to its end."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.slow
def test_sigint_half_way_then_resume_loses_and_repeats_nothing(tmp_path):
    p = short(tmp_path, runs=200, duration=1.0, name="long")
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    cmd = [sys.executable, "-m", "vehest_can.cli", "campaign", str(p), "--no-plots", "-j", "2", "--batch-size", "4"]
    proc = subprocess.Popen([*cmd, "-o", str(tmp_path / "a")], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env, start_new_session=True, preexec_fn=_sigint_default)
    parts = tmp_path / "a" / "runs"
    deadline = time.monotonic() + 300  # a busy machine writes its first parts late
    while len(list(parts.glob("part-*.parquet"))) < 15 and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)  # as a terminal's Ctrl-C: the whole process group
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "interrupted:" in err and "the same command resumes" in err
    c = load_campaign(p)
    kept = Store(tmp_path / "a", c).table(columns=["run"]).column("run").to_pylist()
    assert 0 < len(kept) < 200 and len(set(kept)) == len(kept)
    r = subprocess.run([*cmd, "-o", str(tmp_path / "a")], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    assert f"{len(kept)} already done" in r.stdout
    whole = subprocess.run([*cmd, "-o", str(tmp_path / "b")], capture_output=True, text=True, env=env)
    assert whole.returncode == 0, whole.stderr
    resumed, uninterrupted = frame(Store(tmp_path / "a", c)), frame(Store(tmp_path / "b", c))
    assert resumed["run"] == list(range(200))
    assert resumed == uninterrupted


@pytest.mark.slow
def test_the_worst_run_re_runs_alone_to_the_same_metric(tmp_path, capsys):
    p = spec(tmp_path, """
[campaign]
name = "tf"
base = "chassis_relation_70kph"
runs = 6
seed = 3
metrics = ["variants.skfmec-fixed.rms_pct.*"]
[[vary]]
key = "vehicle.mass_delta_kg"
dist = "uniform"
low = -100
high = 400
[[vary]]
key = "duration_s"
dist = "list"
values = [2.0]
[[acceptance]]
metric = "variants.skfmec-fixed.rms_pct.FL"
max = 7.0
""")
    assert main(["campaign", str(p), "-o", str(tmp_path / "out"), "-j", "2"]) == 0
    out = capsys.readouterr().out
    assert "acceptance (pass rate" in out and "worst run #" in out
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    worst = summary["metrics"]["variants.skfmec-fixed.rms_pct.FL"]
    scenario_file = Path(summary["worst_run_scenarios"][str(worst["worst_run"])])
    assert (tmp_path / "out" / "variants.skfmec-fixed.rms_pct.FL.png").stat().st_size > 10_000
    from vehest_can.schema import read_toml
    doc = read_toml(scenario_file)
    again = flatten(systems.run(system_for(doc), doc, scenario_file, None, doc["seed"]))
    assert again["variants.skfmec-fixed.rms_pct.FL"] == worst["worst"]
    # and it is the loaded car: a worse inner front tyre than the campaign's median
    assert worst["worst"] > worst["median"]


def test_write_run_scenario_is_a_loadable_scenario(tmp_path):
    c = load_campaign(short(tmp_path, runs=3))
    f = write_run_scenario(c, 2, tmp_path / "run2.toml")
    from vehest_can.systems.driveline.scenario import load_driveline_scenario
    sc = load_driveline_scenario(f)
    assert sc.duration_s == 1.5 and sc.seed == c.run_doc(2)[0]["seed"]


@pytest.mark.parametrize("argv, problem", [
    (["-j", "0"], "--workers must be at least 1"),
    (["--batch-size", "0"], "--batch-size must be at least 1"),
    (["--seed", "-1"], "--seed -1: must be an integer"),
])
def test_bad_cli_arguments_are_errors(tmp_path, capsys, argv, problem):
    assert main(["campaign", str(short(tmp_path, runs=2)), *argv]) == 1
    assert problem in capsys.readouterr().err


@pytest.mark.parametrize("argv, problem", [
    (["tireforce_small", "--runs", "0"], "--runs must be at least 1"),
    (["tireforce_small", "--repeats", "-1"], "--repeats must be at least 1"),
    (["tireforce_small", "-j", "0"], "--workers must be at least 1"),
    (["tireforce_small", "--batch-size", "0"], "--batch-size must be at least 1"),
    (["no_such_campaign"], "cannot read"),
])
def test_bad_bench_arguments_are_errors_before_any_run(capsys, argv, problem):
    with pytest.raises(SystemExit) as e:
        main(["study", "campaign.throughput", *argv])
    assert e.value.code == 2 and problem in capsys.readouterr().err


def test_another_seed_is_another_draw_of_the_same_spread(tmp_path, capsys):
    """--seed draws other runs from the same distributions, into a folder of their own."""
    p = short(tmp_path, runs=2, duration=0.5)
    assert main(["campaign", str(p), "-o", str(tmp_path / "a"), "--no-plots", "-j", "1"]) == 0
    assert main(["campaign", str(p), "--seed", "777", "--no-plots", "-j", "1", "-o", str(tmp_path / "b")]) == 0
    assert "short-seed777: 2 runs, 0 failed" in capsys.readouterr().out
    import pyarrow.parquet as pq
    a, b = (pq.read_table(tmp_path / d / "runs").column("seed").to_pylist() for d in ("a", "b"))
    assert len(a) == len(b) == 2 and not set(a) & set(b)


def test_a_missing_campaign_file_is_an_error(tmp_path, capsys):
    assert main(["campaign", str(tmp_path / "none.toml")]) == 1
    assert "cannot read" in capsys.readouterr().err


@pytest.mark.slow
def test_shipped_campaigns_load_and_the_small_ones_run(tmp_path, capsys):
    from vehest_can.paths import shipped_dir
    shipped = sorted(shipped_dir("campaigns", "firmware_sim/campaigns", "*.toml").glob("*.toml"))
    assert {p.stem for p in shipped} >= {"driveline_small", "driveline_spread", "tireforce_small", "tireforce_payload"}
    for p in shipped:
        assert load_campaign(p).runs >= 12
    assert main(["campaign", "tireforce_small", "-o", str(tmp_path / "tf"), "--no-plots"]) == 0
    assert "tireforce_small: 12 runs, 0 failed" in capsys.readouterr().out


def test_list_items_are_set_by_index(tmp_path):
    c = load_campaign(spec(tmp_path, """
[campaign]
base = "chassis_relation_70kph"
runs = 1
[[vary]]
key = "road.mu[0][1]"
dist = "list"
values = [0.4]
"""))
    assert c.run_doc(0)[0]["road"]["mu"] == [[0.0, 0.4]]
    with pytest.raises(ScenarioError, match=r"road.mu\[5\]\[1\]: the base scenario has no item \[5\]"):
        load_campaign(spec(tmp_path, "[campaign]\nbase = 'chassis_relation_70kph'\nruns = 1\n[[vary]]\n"
                                     "key = 'road.mu[5][1]'\ndist = 'list'\nvalues = [0.4]\n", "b.toml"))


def test_faults_from_the_catalogue_are_campaign_parameters(tmp_path):
    c = load_campaign(spec(tmp_path, """
[campaign]
base = "launch_2nd"
runs = 2
[[vary]]
key = "fault"
dist = "grid"
values = ["", "drop:DLS_Sensors:p=0.5;corrupt_crc:DLS_Sensors:p=0.2"]
[[vary]]
key = "duration_s"
dist = "list"
values = [1.5]
"""))
    store = Store(tmp_path / "out", c)
    assert execute(c, store, workers=1)["failed"] == 0
    t = frame(store)
    assert t["param.fault"] == ["", "drop:DLS_Sensors:p=0.5;corrupt_crc:DLS_Sensors:p=0.2"]
    assert t["metric.counters.crc_error"][0] == 0 and t["metric.counters.crc_error"][1] > 50
    assert t["metric.counters.timeout"][0] == 0
    assert t["metric.T.valid_fraction"][0] > 0.9 and t["metric.T.valid_fraction"][1] < t["metric.T.valid_fraction"][0]
    # without faults, the fault path's estimate is the in-process run's (the injectors pass it through)
    doc, _ = c.run_doc(0)
    plain = flatten(systems.run(system_for(doc), doc, c.base_path, None, 0))
    assert abs(plain["speeds+torque.rms_est_minus_truth_nm"] - t["metric.T.rms_est_minus_truth"][0]) < 0.5


@pytest.mark.parametrize("values, problem", [
    ('["nosuch:DLS_Sensors"]', "vary[0].values[0]: --fault 'nosuch:DLS_Sensors': unknown fault kind 'nosuch'"),
    ("[3]", "vary[0].values[0]: must be a fault string"),
])
def test_bad_fault_strings_are_clear_errors(tmp_path, values, problem):
    with pytest.raises(ScenarioError) as err:
        load_campaign(spec(tmp_path, f"[campaign]\nbase = 'launch_2nd'\nruns = 1\n[[vary]]\nkey = 'fault'\n"
                                     f"dist = 'list'\nvalues = {values}\n"))
    assert problem in str(err.value)


def test_faults_on_a_system_that_takes_none_are_refused(tmp_path):
    with pytest.raises(ScenarioError, match="the tireforce system's runs take no faults"):
        load_campaign(spec(tmp_path, "[campaign]\nbase = 'chassis_relation_70kph'\nruns = 1\n[[vary]]\n"
                                     "key = 'fault'\ndist = 'list'\nvalues = ['']\n"))


def test_runs_without_a_value_are_counted_not_hidden(tmp_path):
    """A run that ran but gave NaN (e.g. a camber wheel without a result) is not in the median/p95/
    worst; the summary and the table say how many there were, and a metric without any value says so."""
    import pyarrow as pa

    from vehest_can.campaign.report import table_text

    c = load_campaign(short(tmp_path, runs=4))
    t = pa.table({"run": [0, 1, 2, 3], "error": [None, None, None, "boom"],
                  "metric.speeds+torque.rms_est_minus_truth_nm": [1.0, float("nan"), 2.0, float("nan")],
                  "metric.never": [float("nan")] * 4, "param.duration_s": [1.5] * 4})
    s = summarize(c, t)
    m = s["metrics"]["speeds+torque.rms_est_minus_truth_nm"]
    assert m["no_value"] == 1 and m["worst"] == 2.0 and m["median"] == 1.5
    assert s["metrics"]["never"] == {"no_value": 3}
    text = table_text(s)
    assert "(1 runs without a value, not in these figures)" in text
    assert "never" in text and "no value in any of the 3 runs" in text
    assert s["acceptance"][0]["passed"] == 2  # the two finite runs; NaN and the failed run never pass


@pytest.mark.slow
def test_two_local_dask_clusters_at_once_take_free_loopback_ports():
    pytest.importorskip("distributed")
    import warnings

    from vehest_can.campaign.runner import local_cluster

    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        with local_cluster(1) as a, local_cluster(1) as b:
            servers = [c.scheduler.http_server for c in (a, b)]
            assert {s.address for s in servers} == {"127.0.0.1"}  # nothing listens beyond loopback
            assert len({s.port for s in servers}) == 2 and 8787 not in {s.port for s in servers}
    assert not [w for w in seen if "already in use" in str(w.message)]


PLANTS_CAMPAIGN = """
[campaign]
name = "plants"
base = "chassis_relation_70kph"
runs = 8
seed = 5
metrics = ["variants.skfmec-a.rms_pct.*", "variants.skfmec-a.mass.final_kg"]

[[vary]]
key = "duration_s"
dist = "list"
values = [1.0]

[[vary]]
key = "plant"
dist = "grid"
values = ["veh14", "commonroad_mb"]

[[vary]]
key = "vehicle.mass_delta_kg"
dist = "grid"
values = [0, 200]

[[vary]]
key = "road.mu[0][1]"
dist = "grid"
values = [0.8, 1.1]
"""


@pytest.mark.slow
def test_plant_payload_friction_campaign_is_identical_on_the_pool_and_dask(tmp_path):
    """plant x payload x mu on the local pool and a Dask LocalCluster: the same rows; the plant really
    changes the runs (a run on MB differs from its twin on ours)."""
    pytest.importorskip("distributed")
    pytest.importorskip("vehiclemodels")
    c = load_campaign(spec(tmp_path, PLANTS_CAMPAIGN))
    tables = {}
    # one worker each: every worker process compiles the MB plant once (a few seconds)
    for label, kw in (("pool", {"workers": 1}), ("dask", {"workers": 1, "scheduler": "local-dask"})):
        store = Store(tmp_path / label, c)
        counts = execute(c, store, batch_size=4, **kw)
        assert counts["ran"] == 8 and counts["failed"] == 0
        tables[label] = frame(store)
    assert tables["pool"] == tables["dask"]
    t = tables["pool"]
    assert t["param.plant"] == ["veh14"] * 4 + ["commonroad_mb"] * 4
    fl = t["metric.variants.skfmec-a.rms_pct.FL"]
    assert all(a != b for a, b in zip(fl[:4], fl[4:]))
