"""Car files (vehest_can.carfile): the paper's car is the C defaults byte for byte, the derived
quantities go both ways, CommonRoad's parameter sets are cars the ECU and the plant take, a broken
file is an error naming the key, a scenario may name a car, and the ECU calibrated for a car other
than the paper's still equals its off-line references bit for bit."""
import dataclasses
import math
from fractions import Fraction

import numpy as np
import pytest

from vehest_can import carfile
from vehest_can.carfile import AXLES, CarFile, car_from_dict, cars, load_car, paper_car
from vehest_can.errors import ConfigError, ScenarioError
from vehest_can.native import ffi, lib
from vehest_can.schema import read_toml
from vehest_can.sim.session import run_inprocess
from vehest_can.sim.veh14 import _VEHICLE, Veh14Car
from vehest_can.systems.ecu import Ecu, EcuConfig, check_car

COMMONROAD_CARS = ("commonroad_vehicle1", "commonroad_vehicle2", "commonroad_vehicle3")


def c_bytes(cdata) -> bytes:
    return bytes(ffi.buffer(cdata))


# ---- the paper's car --------------------------------------------------------------------------------

def test_paper_car_is_the_c_defaults_byte_for_byte():
    """EcuConfig(car=paper) and the plant's parameters from paper.toml are the C defaults (the golden
    logs rest on it); another car's are not (so the comparison can fail)."""
    default = ffi.new("vh_ecu_config_t *")
    lib.vh_ecu_config_default(default)
    paper = EcuConfig(car=load_car("paper")).to_c()
    for part in ("tf", "roll"):
        assert c_bytes(ffi.addressof(paper.app, part)) == c_bytes(ffi.addressof(default.app, part)), part
    assert c_bytes(paper) == c_bytes(default)
    assert c_bytes(EcuConfig().to_c()) == c_bytes(default)  # no car: the paper's
    prm = ffi.new("vh_v14_params_t *")
    lib.vh_v14_params_default(prm)
    assert c_bytes(paper_car().veh14_params(ffi, lib)) == c_bytes(prm)
    other = EcuConfig(car=load_car("commonroad_vehicle2")).to_c()
    assert c_bytes(ffi.addressof(other.app, "tf")) != c_bytes(ffi.addressof(default.app, "tf"))
    assert c_bytes(ffi.addressof(other.app, "roll")) != c_bytes(ffi.addressof(default.app, "roll"))
    assert c_bytes(load_car("commonroad_vehicle2").veh14_params(ffi, lib)) != c_bytes(prm)


def test_paper_car_derived_figures_are_the_documented_ones():
    car = paper_car()
    assert car.total_mass_kg == 1814.0
    assert car.anti_roll_bar("front") == pytest.approx(130127, rel=1e-5)   # docs/chassis_plant.md
    assert car.anti_roll_bar("rear") == pytest.approx(84539, rel=1e-5)
    assert car.damper_rate("front") == pytest.approx(672.6, abs=0.05)
    assert car.damper_rate("rear") == pytest.approx(570.4, abs=0.05)
    assert car.cg_height_m - car.roll_axis_height_m == pytest.approx(0.47995, abs=1e-5)


def test_the_data_sheet_keys_are_the_scenario_vehicle_tables():
    """The same names, plant fields and ranges as a scenario's [vehicle] table."""
    for key, (field, spec) in _VEHICLE.items():
        if key in carfile.DATA_SHEET:
            assert carfile.DATA_SHEET[key] == (field, spec), key
        else:
            form = "roll_stiffness" if key.startswith("roll_stiffness") else "roll_damping"
            assert key.startswith(form) and (spec.lo, spec.hi) == {
                "roll_stiffness": (1e3, 1e6), "roll_damping": (0.0, 1e5)}[form], key
    assert set(carfile.DATA_SHEET) | {k for k in _VEHICLE if k.startswith("roll_")} == set(_VEHICLE)


# ---- both forms ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["paper", *COMMONROAD_CARS])
def test_roll_stiffness_and_anti_roll_bar_round_trip(name):
    """k_phi -> bar -> k_phi and bar -> k_phi -> bar, damping <-> dampers, with the plant's formulas."""
    car = load_car(name)
    for axle in AXLES:
        t, k = car._axle(axle)
        kphi, bar = car.roll_stiffness(axle), car.anti_roll_bar(axle)
        as_bar = dataclasses.replace(car, **{f"roll_stiffness_{axle}_nm_per_rad": None,
                                             f"anti_roll_bar_{axle}_nm_per_rad": bar})
        as_kphi = dataclasses.replace(car, **{f"roll_stiffness_{axle}_nm_per_rad": kphi,
                                              f"anti_roll_bar_{axle}_nm_per_rad": None})
        assert as_bar.roll_stiffness(axle) == pytest.approx(kphi, rel=1e-12)
        assert as_kphi.anti_roll_bar(axle) == pytest.approx(bar, rel=1e-9, abs=1e-6)
        # the series formula itself: 1/k_phi = 1/(2 k t^2 + k_arb) + 1/(2 kt t^2)
        assert 1 / kphi == pytest.approx(1 / (2 * k * t * t + bar) + 1 / (2 * car.tyre_stiffness_n_per_m * t * t))
        c, cphi = car.damper_rate(axle), car.roll_damping(axle)
        assert cphi == pytest.approx(2 * c * t * t, rel=1e-12)
        both = dataclasses.replace(car, **{f"roll_damping_{axle}_nms_per_rad": None, f"damper_rate_{axle}_ns_per_m": c})
        assert both.roll_damping(axle) == pytest.approx(cphi, rel=1e-12)


def test_a_car_without_a_bar_round_trips_to_no_bar_and_the_plant_agrees():
    """The rear of commonroad_vehicle1 has no bar: k_phi made from the springs alone comes back as no bar
    (not a -1e-12 residue), in Python and in the plant."""
    car = load_car("commonroad_vehicle1")
    assert car.anti_roll_bar_rear_nm_per_rad == 0.0
    as_kphi = dataclasses.replace(car, roll_stiffness_rear_nm_per_rad=car.roll_stiffness("rear"),
                                  anti_roll_bar_rear_nm_per_rad=None)
    assert as_kphi.anti_roll_bar("rear") == 0.0
    p = ffi.new("vh_v14_t *")
    assert lib.vh_v14_init(p, as_kphi.veh14_params(ffi, lib)) == lib.VH_OK
    assert p.k_arb_r == 0.0 and p.k_arb_f > 0.0   # and a front bar


# ---- CommonRoad ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", COMMONROAD_CARS)
def test_every_commonroad_car_is_taken_by_the_ecu_and_the_plant(name):
    from vehiclemodels import parameters_vehicle1, parameters_vehicle2, parameters_vehicle3

    p = {"commonroad_vehicle1": parameters_vehicle1.parameters_vehicle1,
         "commonroad_vehicle2": parameters_vehicle2.parameters_vehicle2,
         "commonroad_vehicle3": parameters_vehicle3.parameters_vehicle3}[name]()
    car = load_car(name)
    assert car.sprung_mass_kg == p.m_s and car.unsprung_mass_front_kg == p.m_uf / 2
    assert car.half_track_rear_m == p.T_r / 2 and car.damper_rate("front") == p.K_sdf
    assert car.anti_roll_bar("front") == -p.K_tsf > 0 and car.drag_area_m2 == 0.0  # MB's sign: restoring < 0
    assert car.total_mass_kg == pytest.approx(p.m, rel=1e-6)
    check_car(car)
    ecu = Ecu(EcuConfig(car=car))
    assert ecu.c.app.tf.skf.prm is not None
    tfa = ecu.c.app.tf.tfa.prm
    # SKFMEC-A's model mass: the nearest fraction the integer TX takes (CommonRoad's masses have no exact one)
    assert abs(Fraction(tfa.m_num, tfa.m_den) - Fraction(car.total_mass_kg)) <= Fraction(1, 2 * tfa.m_den)
    assert tfa.m_den >= 10_000
    plant = ffi.new("vh_v14_t *")
    assert lib.vh_v14_init(plant, car.veh14_params(ffi, lib)) == lib.VH_OK
    assert plant.m == pytest.approx(car.total_mass_kg, rel=1e-15)


def test_commonroad_vehicle4_has_no_multibody_data_and_says_so():
    with pytest.raises(ConfigError, match=r"commonroad_vehicle4: .*parameters_vehicle4 .*no multi-body data .*m_s"):
        load_car("commonroad_vehicle4")


def test_names_and_paths():
    assert {"paper", *COMMONROAD_CARS} <= set(cars())
    assert load_car("paper") is paper_car()
    assert load_car(str(paper_car().path)) == dataclasses.replace(paper_car())
    with pytest.raises(ConfigError, match="neither a car file .* nor a shipped car .*commonroad_vehicle2"):
        load_car("no_such_car")


# ---- errors name the key --------------------------------------------------------------------------------

def paper_doc() -> dict:
    return read_toml(paper_car().path)


@pytest.mark.parametrize("change, key, words", [
    ({"sprung_mass_kg": -1661.0}, "sprung_mass_kg", ["-1661.0", "[200, 5000]"]),
    ({"sprung_mass_kg": "heavy"}, "sprung_mass_kg", ["'heavy'", "a string", "[200, 5000]"]),
    ({"sprung_mas_kg": 1661.0}, "sprung_mas_kg", ["unknown key"]),
    ({"anti_roll_bar_front_nm_per_rad": 1e5}, "anti_roll_bar_front_nm_per_rad",
     ["roll_stiffness_front_nm_per_rad", "not both"]),
    ({"roll_stiffness_front_nm_per_rad": None, "anti_roll_bar_front_nm_per_rad": -40000.0},
     "anti_roll_bar_front_nm_per_rad", ["-40000.0", "suspension roll stiffness must stay positive"]),
    ({"roll_stiffness_rear_nm_per_rad": 5e5}, "roll_stiffness_rear_nm_per_rad", ["500000.0", "tyres' own"]),
    ({"roll_centre_height_front_m": 0.39, "cg_height_m": 0.3}, "roll_centre_height_front_m", ["below the sprung CG"]),
    ({"roll_damping_rear_nms_per_rad": None}, "roll_damping_rear_nms_per_rad", ["missing", "damper_rate_rear_ns_per_m"]),
    ({"wheel_radius_m": None}, "wheel_radius_m", ["missing"]),
    ({"roll_axis_to_cg_m": 0.3}, "roll_axis_to_cg_m", ["0.3", "h - h_ra"]),
])
def test_a_broken_car_file_names_the_key_its_value_and_range(tmp_path, change, key, words):
    doc = paper_doc()
    for k, v in change.items():
        if v is None:
            doc.pop(k)
        else:
            doc[k] = v
    path = tmp_path / "broken.toml"
    import tomli_w

    path.write_text(tomli_w.dumps(doc))
    with pytest.raises(ConfigError) as exc:
        load_car(path)
    msg = str(exc.value)
    assert msg.startswith(f"{path}: {key}: "), msg
    for w in words:
        assert w in msg, msg


def test_a_car_file_with_bad_tyre_coefficients_names_them(tmp_path):
    doc = paper_doc()
    doc["tyre"]["lateral_coefficients"] = [1.3, 2.0]
    with pytest.raises(ConfigError, match=r"tyre.lateral_coefficients: \[1.3, 2.0\]: must be a list of 9"):
        car_from_dict(doc, tmp_path / "t.toml")


def test_a_c_refusal_names_the_key_the_ranges_missed():
    """A tyre whose shape factor C = 2.5 is in the file's range (any number) but no peaked curve: the plant's
    vh_v14_init refuses it, and the message names the key (the one whose paper value makes C accept it);
    the same for a PAC2002 set (the plant plays the car's tyre)."""
    paper = paper_car()
    car = dataclasses.replace(paper, name="bent", path=None, lateral_coefficients=(2.5, *paper.lateral_coefficients[1:]))
    with pytest.raises(ConfigError, match=r"bent: lateral_coefficients: \(2.5, .*vh_v14_init.*paper's"):
        check_car(car)
    v2 = load_car("commonroad_vehicle2")
    car = dataclasses.replace(v2, pac2002_coefficients=(2.5, *v2.pac2002_coefficients[1:]))
    with pytest.raises(ConfigError, match=r"commonroad_vehicle2: pac2002_coefficients: \(2.5, .*vh_v14_init.*"
                                          r"without it the car is accepted"):
        check_car(car)


def test_an_ecu_refusal_names_the_key():
    """A roll damping of zero gets through a hand-made CarFile but not the roll UKF's check."""
    car = dataclasses.replace(paper_car(), roll_damping_front_nms_per_rad=0.0)
    with pytest.raises(ConfigError, match=r"roll_damping_front_nms_per_rad: 0.0 is refused by vh_roll_params_check"):
        Ecu(EcuConfig(car=car))


# ---- a scenario naming a car ----------------------------------------------------------------------------

def tireforce_doc(**top) -> dict:
    from vehest_can.systems.tireforce.scenario import tireforce_scenario_path

    doc = read_toml(tireforce_scenario_path("chassis_paper_mu_drop"))
    doc.update(top)
    return doc


def test_a_scenario_naming_a_car_runs_it_and_its_vehicle_table_overrides(tmp_path):
    from vehest_can.systems.tireforce.scenario import tireforce_scenario_from_dict

    car = load_car("commonroad_vehicle2")
    sc = tireforce_scenario_from_dict(tireforce_doc(car="commonroad_vehicle2", vehicle={}), tmp_path / "s.toml")
    assert sc.car is car
    assert c_bytes(sc.plant_params(ffi, lib)) == c_bytes(car.veh14_params(ffi, lib))
    sc2 = tireforce_scenario_from_dict(tireforce_doc(car="commonroad_vehicle2", vehicle={"yaw_inertia_kgm2": 2000.0,
                                                                                         "mass_delta_kg": 50.0}),
                                       tmp_path / "s.toml")
    prm = sc2.plant_params(ffi, lib)
    assert prm.iz == 2000.0 and prm.ms == car.sprung_mass_kg + 50.0 and prm.kphi_f == car.roll_stiffness("front")
    # a path relative to the scenario file
    (tmp_path / "cars").mkdir()
    (tmp_path / "cars" / "mine.toml").write_text(paper_car().path.read_text().replace('name = "paper"', 'name = "mine"'))
    sc3 = tireforce_scenario_from_dict(tireforce_doc(car="cars/mine.toml"), tmp_path / "s.toml")
    assert sc3.car.name == "mine" and c_bytes(sc3.plant_params(ffi, lib)) != c_bytes(sc2.plant_params(ffi, lib))


def test_a_scenario_naming_a_bad_car_says_which(tmp_path):
    from vehest_can.systems.tireforce.scenario import tireforce_scenario_from_dict

    (tmp_path / "bad.toml").write_text(paper_car().path.read_text().replace("sprung_mass_kg = 1661.0", "sprung_mass_kg = 9e9"))
    with pytest.raises(ScenarioError, match=r"s.toml: car: .*bad.toml: sprung_mass_kg: 9000000000.0 is out of range"):
        tireforce_scenario_from_dict(tireforce_doc(car="bad.toml"), tmp_path / "s.toml")
    with pytest.raises(ScenarioError, match=r"s.toml: car: car 'nope': neither"):
        tireforce_scenario_from_dict(tireforce_doc(car="nope"), tmp_path / "s.toml")


# ---- the ECU calibrated for another car == its off-line references, bit for bit -----------------------

def test_bus_equals_the_references_for_a_commonroad_car(tmp_path):
    """commonroad_vehicle2 in the plant and the ECU: the fixed-point SKFMEC's forces and SKFMEC-A's forces
    and mass on the bus equal the array API calibrated for the same car (what the demo's metrics check);
    calibrated for the paper's car instead, they do not."""
    from vehest_can.sim.report import decode
    from vehest_can.systems.tireforce import api as tf
    from vehest_can.systems.tireforce import report
    from vehest_can.systems.tireforce.adaptive import AdaptiveConfig, AdaptiveFixed
    from vehest_can.systems.tireforce.scenario import tireforce_scenario_from_dict

    sc = tireforce_scenario_from_dict(tireforce_doc(car="commonroad_vehicle2", duration_s=1.5), tmp_path / "s.toml")
    car = sc.car
    session = run_inprocess(Veh14Car(sc), Ecu(EcuConfig(car=car)))
    dec = report.decode_inputs(session.messages())
    est = decode(session, "VEHEST_TireForceEst")
    on = est["SkfmecQ_Health"] > 0
    bus_fy = np.column_stack([est[f"Fy{i}"] for i in range(1, 5)])[on]
    enc = lambda v: np.floor(v / 0.5 + 0.5) * 0.5  # noqa: E731
    assert on.sum() > 500
    ref = report.run_estimators(dec, (tf.FIXED,), car=car)[tf.FIXED]
    assert np.array_equal(bus_fy, enc(ref.fy[on]))
    paper_ref = report.run_estimators(dec, (tf.FIXED,))[tf.FIXED]
    assert not np.array_equal(bus_fy, enc(paper_ref.fy[on]))

    ada = decode(session, "VEHEST_TireForceAdaptive")
    on_a = ada["SkfmecA_Health"] > 0
    fixed = AdaptiveFixed(tf.SkfConfig.for_car(car), AdaptiveConfig.for_car(car))
    ref_a = fixed.run(dec.for_filter(), dec.mask, dec.ride)
    bus_a = np.column_stack([ada[f"FyA{i}"] for i in range(1, 5)] + [ada["EstMass"]])[on_a]
    want = np.column_stack([enc(ref_a.fy), enc(np.asarray(ref_a.mass))])[on_a]
    assert on_a.sum() > 50 and np.array_equal(bus_a, want)
    m = Fraction(fixed.params.m_num, fixed.params.m_den)  # the mass the ECU sends k times, exactly
    exact = [math.floor(Fraction(int(k), 2**lib.VH_TFA_FK) * m * 2 + Fraction(1, 2)) * 0.5 for k in ref_a.raw["k"][on_a]]
    assert list(bus_a[:, 4]) == exact
    # the scenario's payload on the CommonRoad car, found from the ride heights
    assert report.true_mass(sc) == car.total_mass_kg + 200.0
    assert abs(bus_a[-1, 4] / report.true_mass(sc) - 1) < 0.01


def test_roll_bus_equals_its_rerun_for_a_commonroad_car(tmp_path):
    from vehest_can.systems.roll import report
    from vehest_can.systems.roll.scenario import RollCar, roll_scenario_from_dict, roll_scenario_path

    doc = read_toml(roll_scenario_path("roll_paper_72kph_active"))
    doc.update(car="commonroad_vehicle2", duration_s=1.0)
    sc = roll_scenario_from_dict(doc, tmp_path / "r.toml")
    car = carfile.car_of(sc)
    assert car is load_car("commonroad_vehicle2")
    session = run_inprocess(RollCar(sc), Ecu(EcuConfig(car=car)))
    assert report.rerun(session, car)["ecu_equals_array_api"]
    assert not report.rerun(session)["ecu_equals_array_api"]  # the paper's calibration is another filter


def test_carfile_is_a_frozen_dataclass_with_the_keys():
    fields = {f.name for f in dataclasses.fields(CarFile)}
    assert {"name", "description", "path", *carfile.DATA_SHEET} <= fields
    with pytest.raises(dataclasses.FrozenInstanceError):
        paper_car().sprung_mass_kg = 1.0  # type: ignore[misc]


def test_the_car_a_plant_plays():
    """played_by: the paper's car on CommonRoad's plant is paper_mb's data (vehicle 2's PAC2002 tyre and
    K_lt, no 1987 set); a car with its own PAC2002 set stays as it is there (and MB runs that set, not its
    base vehicle's); on our plant a car keeps its tyre and loses the compliance the plant does not model."""
    from vehest_can.native import ffi, lib
    from vehest_can.sim.car import played_by
    from vehest_can.sim.mbplant import mb_parameters

    paper, paper_mb = paper_car(), load_car("paper_mb")
    on_mb = played_by(paper, "commonroad_mb")
    assert on_mb.pac2002_coefficients == paper_mb.pac2002_coefficients
    assert on_mb.lateral_compliance_m_per_n == paper_mb.lateral_compliance_m_per_n
    assert on_mb.lateral_coefficients is None and on_mb.sprung_mass_kg == paper.sprung_mass_kg
    assert played_by(paper, "veh14") is paper and played_by(paper_mb, "commonroad_mb") is paper_mb
    v2 = load_car("commonroad_vehicle2")
    assert played_by(v2, "veh14").lateral_compliance_m_per_n == 0.0
    assert played_by(v2, "veh14").pac2002_coefficients == v2.pac2002_coefficients
    own = dataclasses.replace(v2, pac2002_coefficients=(1.4, 0.9, -0.1, -18.0, 1.6, 1.1, 0.4, 20.0),
                              lateral_compliance_m_per_n=2e-5)
    p = mb_parameters(own.veh14_params(ffi, lib), 2, own.lateral_compliance_m_per_n)
    assert (p.tire.p_cy1, p.tire.p_dy1, p.tire.p_ky1, p.tire.p_kx1, p.K_lt) == (1.4, 0.9, -18.0, 20.0, 2e-5)
