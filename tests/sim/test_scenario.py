"""Scenario files: the loader's validation (every error names file and key) and the shipped scenarios."""
from __future__ import annotations

import dataclasses
import math
import textwrap

import numpy as np
import pytest

from vehest_can.errors import ConfigError, ScenarioError
from vehest_can.native import ffi, lib
from vehest_can.sim.powertrain import PowertrainScenario
from vehest_can.sim.scenario import DT
from vehest_can.systems.driveline.scenario import (
    driveline_scenario_dir,
    driveline_scenario_from_dict,
    list_driveline_scenarios,
    load_driveline_scenario,
)

GOOD = """\
kind = "driveline"
name = "mine"
description = "a test"
duration_s = 2.0
seed = 3

[driver]
gear = 2
throttle = [[0.0, 0.0], [0.5, 0.2], [1.0, 0.2]]
"""


def write(tmp_path, text, name="s.toml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


# ---- shipped scenarios ---------------------------------------------------------------------

def test_shipped_scenarios_are_found_and_load():
    names = list_driveline_scenarios()
    assert {"launch_2nd", "tip_in_tip_out"} <= set(names)
    assert driveline_scenario_dir().is_dir()
    for name in names:
        sc = load_driveline_scenario(name)
        assert sc.name == name and sc.path == driveline_scenario_dir() / f"{name}.toml"
        assert sc.description and sc.duration_s > 0


def test_launch_2nd_is_the_papers_case():
    sc = load_driveline_scenario("launch_2nd")
    assert sc.gear == 2 and sc.initial_speed_kmh == 0.0
    assert 8.0 <= sc.duration_s <= 15.0
    thr = sc.throttle_at(sc.times())
    assert thr[0] == 0.0 and thr.max() > 0.3  # launch from rest with a throttle step/ramp
    tr = sc.run_truth(ffi, lib)
    assert len(tr) == sc.n_steps == round(sc.duration_s / DT)
    np.testing.assert_allclose(tr["t"], sc.times())
    np.testing.assert_allclose(tr["throttle"], thr)
    assert tr["v"][0] < 0.1 and tr["v"].max() * 3.6 > 20.0
    assert tr["sr"][np.argmax(tr["to"])] < 0.6  # peak torque while the converter multiplies
    again = sc.run_truth(ffi, lib)
    for name in tr.dtype.names:
        assert np.array_equal(tr[name], again[name])  # same file, same seed: same run


def test_tip_in_tip_out_starts_rolling_and_goes_into_overrun():
    sc = load_driveline_scenario("tip_in_tip_out")
    tr = sc.run_truth(ffi, lib)
    assert tr["v"][0] * 3.6 == pytest.approx(sc.initial_speed_kmh, rel=0.01)
    assert (tr["sr"] > 1.0).any() and (tr["to"] < 0).any()  # lift-off: wheels drive the engine


# ---- a good file and its conversions -------------------------------------------------------

def test_good_file_and_defaults(tmp_path):
    sc = load_driveline_scenario(write(tmp_path, GOOD))
    assert (sc.name, sc.duration_s, sc.seed, sc.gear, sc.initial_speed_kmh) == ("mine", 2.0, 3, 2, 0.0)
    prm = ffi.new("vh_dlp_params_t *")
    lib.vh_dlp_params_default(prm)
    assert (sc.road_std_nm, sc.road_bandwidth_hz) == (prm.road_std, prm.road_bw)
    cfg = ffi.new("vh_dls_config_t *")
    lib.vh_dls_config_default(cfg)
    assert dict(sc.sensors)["shaft_torque_std_nm"] == cfg.noise_std[lib.VH_DLS_CH_TO]
    with pytest.raises(dataclasses.FrozenInstanceError):
        sc.gear = 3


def test_throttle_profile_is_piecewise_linear_and_held(tmp_path):
    sc = load_driveline_scenario(write(tmp_path, GOOD.replace("[[0.0, 0.0], [0.5, 0.2], [1.0, 0.2]]",
                                                    "[[0.2, 0.1], [0.6, 0.5], [1.0, 0.3]]")))
    t = np.array([0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 5.0])
    np.testing.assert_allclose(sc.throttle_at(t), [0.1, 0.1, 0.3, 0.5, 0.4, 0.3, 0.3])
    assert isinstance(sc.throttle_at(t), np.ndarray)


def test_overrides_reach_the_c_structs(tmp_path):
    path = write(tmp_path, "initial_speed_kmh = 30\n" + GOOD + textwrap.dedent("""
        [road]
        roughness_std_nm = 55.5
        roughness_bandwidth_hz = 12
        [vehicle]
        vehicle_inertia_kgm2 = 180.0
        shaft_stiffness_nm_per_rad = 12000
        gear_ratios = [0.3, 0.45, 0.7, 0.95, 1.2]
        [sensors]
        wheel_speed_std_rad_s = 0.25
        shaft_torque_std_nm = 3
    """))
    sc = load_driveline_scenario(path)
    prm = sc.plant_params(ffi, lib)
    assert (prm.road_std, prm.road_bw, prm.jv, prm.ks) == (55.5, 12.0, 180.0, 12000.0)
    assert list(prm.ri) == [0.3, 0.45, 0.7, 0.95, 1.2]
    assert prm.jo == 0.016  # not overridden: the plant default
    cfg = sc.node_config(ffi, lib)
    assert (cfg.noise_std[1], cfg.noise_std[2], cfg.noise_std[3]) == (0.25, 0.25, 3.0)
    assert cfg.seed == sc.node_seed != sc.seed
    p = sc.make_plant(ffi, lib)
    assert p.truth.v * 3.6 == pytest.approx(30.0) and p.seed == 3
    assert sc.make_node(ffi, lib).cfg.noise_std[3] == 3.0


# ---- every error class names file, key and problem ------------------------------------------

BAD = [
    # (replace this, with this, expected dotted key, words in the problem)
    ('name = "mine"', 'name = "mine"\ncolour = "red"', "colour", "unknown key"),
    ('name = "mine"\n', "", "name", "missing"),
    ('name = "mine"', 'name = "  "', "name", "empty"),
    ('name = "mine"', "name = 5", "name", "must be a string"),
    ("duration_s = 2.0", 'duration_s = "2"', "duration_s", "must be a number"),
    ("duration_s = 2.0", "duration_s = 0", "duration_s", "out of range"),
    ("duration_s = 2.0", "duration_s = -1.0", "duration_s", "out of range"),
    ("duration_s = 2.0", "duration_s = nan", "duration_s", "must be a number"),
    ("duration_s = 2.0", "duration_s = 1e5", "duration_s", "out of range"),
    ("seed = 3", "seed = true", "seed", "not a boolean"),
    ("seed = 3", "seed = 1.5", "seed", "must be an integer"),
    ("seed = 3", "seed = -1", "seed", "out of range"),
    ("seed = 3", "initial_speed_kmh = 300", "initial_speed_kmh", "out of range"),
    ("gear = 2", "gear = 7", "driver.gear", "out of range"),
    ("gear = 2", 'gear = "2nd"', "driver.gear", "must be an integer"),
    ("gear = 2\n", "", "driver.gear", "missing"),
    ("gear = 2", "gear = 2\nbrake = 1", "driver.brake", "unknown key"),
    ("[[0.0, 0.0], [0.5, 0.2], [1.0, 0.2]]", "[[0.0, 0.0], [0.5, 1.5]]", "driver.throttle[1][1]", "out of range"),
    ("[[0.0, 0.0], [0.5, 0.2], [1.0, 0.2]]", "[[0.0, 0.0], [0.5, 0.2], [0.4, 0.2]]", "driver.throttle[2]",
     "must increase"),
    ("[[0.0, 0.0], [0.5, 0.2], [1.0, 0.2]]", "[[0.0, 0.0], [0.0, 0.2]]", "driver.throttle[1]", "must increase"),
    ("[[0.0, 0.0], [0.5, 0.2], [1.0, 0.2]]", "[[0.0, 0.0], [0.5]]", "driver.throttle[1]", "point (2 values)"),
    ("[[0.0, 0.0], [0.5, 0.2], [1.0, 0.2]]", "[[-1.0, 0.0]]", "driver.throttle[0][0]", "out of range"),
    ("[[0.0, 0.0], [0.5, 0.2], [1.0, 0.2]]", "[]", "driver.throttle", "non-empty list"),
    ("[[0.0, 0.0], [0.5, 0.2], [1.0, 0.2]]", "0.3", "driver.throttle", "non-empty list"),
    ("[[0.0, 0.0], [0.5, 0.2], [1.0, 0.2]]", '[[0.0, "x"]]', "driver.throttle[0][1]", "must be a number"),
]
EXTRA = [
    ("[road]\nroughness_std_nm = -1", "road.roughness_std_nm", "out of range"),
    ("[road]\nroughness_bandwidth_hz = 0", "road.roughness_bandwidth_hz", "out of range"),
    ("[road]\nroughnes_std_nm = 1", "road.roughnes_std_nm", "unknown key"),
    ("[vehicle]\nfinal_drive_ratio = -0.3", "vehicle.final_drive_ratio", "out of range"),
    ("[vehicle]\nmass_kg = 1500", "vehicle.mass_kg", "unknown key"),
    ("[vehicle]\ngear_ratios = [0.3, 0.4]", "vehicle.gear_ratios", "list of 5"),
    ("[vehicle]\ngear_ratios = [0.3, 0.4, 0.6, 0.9, 9.0]", "vehicle.gear_ratios[4]", "out of range"),
    ("[vehicle]\nwheel_radius_m = [0.3]", "vehicle.wheel_radius_m", "must be a number"),
    # each in range, together too fast for the 0.5 ms step: the plant's own check, named [vehicle]
    ("[vehicle]\noutput_inertia_kgm2 = 0.008\ngear_ratios = [0.2, 0.43, 0.66, 0.91, 1.18]", "vehicle",
     "refuses"),
    ("[sensors]\nshaft_torque_std_nm = -7", "sensors.shaft_torque_std_nm", "out of range"),
    ("[sensors]\nshaft_torque_std_nm = inf", "sensors.shaft_torque_std_nm", "must be a number"),
    ("[sensors]\nyaw_rate_std = 1", "sensors.yaw_rate_std", "unknown key"),
]


def check_error(path, key, words):
    with pytest.raises(ScenarioError) as info:
        load_driveline_scenario(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}: {key}: "), msg
    assert words in msg, msg
    assert isinstance(info.value, ConfigError)  # the CLI's error root catches it


@pytest.mark.parametrize("old,new,key,words", BAD, ids=[b[2] + ":" + b[3] for b in BAD])
def test_bad_values_name_file_and_key(tmp_path, old, new, key, words):
    assert old in GOOD
    check_error(write(tmp_path, GOOD.replace(old, new, 1)), key, words)


@pytest.mark.parametrize("tail,key,words", EXTRA, ids=[e[1] + ":" + e[2] for e in EXTRA])
def test_bad_tables_name_file_and_key(tmp_path, tail, key, words):
    check_error(write(tmp_path, GOOD + "\n" + tail + "\n"), key, words)


def test_missing_driver_table(tmp_path):
    check_error(write(tmp_path, GOOD.split("[driver]")[0]), "driver", "missing")


@pytest.mark.parametrize("table", ["driver", "road", "vehicle", "sensors"])
def test_table_that_is_not_a_table(tmp_path, table):
    text = f"{table} = 3\n" + (GOOD.split("[driver]")[0] if table == "driver" else GOOD)
    check_error(write(tmp_path, text), table, "must be a table")


def test_toml_syntax_error_names_the_file(tmp_path):
    path = write(tmp_path, GOOD + "\nthis is = = not toml\n")
    with pytest.raises(ScenarioError, match="TOML syntax") as info:
        load_driveline_scenario(path)
    assert str(path) in str(info.value)


def test_missing_file(tmp_path):
    path = tmp_path / "nope.toml"
    with pytest.raises(ScenarioError, match="cannot read") as info:
        load_driveline_scenario(path)
    assert str(path) in str(info.value)
    with pytest.raises(ScenarioError, match="no_such_scenario"):
        load_driveline_scenario("no_such_scenario")


def test_from_dict_names_its_source():
    with pytest.raises(ScenarioError, match=r"^<scenario>: duration_s: missing"):
        driveline_scenario_from_dict({"kind": "driveline", "name": "x", "driver": {"gear": 1, "throttle": [[0, 0]]}})
    sc = driveline_scenario_from_dict({"kind": "driveline", "name": "x", "duration_s": 1,
                                       "driver": {"gear": 1, "throttle": [[0, 0]]}})
    assert isinstance(sc, PowertrainScenario) and sc.n_steps == 2000 and not math.isnan(sc.road_std_nm)
