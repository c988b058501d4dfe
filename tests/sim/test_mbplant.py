"""CommonRoad's multi-body model behind our car contract (vehest_can.sim.mbplant): held against the
package's own integration, its sensors body-fixed, its actuators acting, and our plant beside it."""
from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("vehiclemodels")
pytest.importorskip("numba")

from vehest_can.errors import ScenarioError  # noqa: E402
from vehest_can.native import ffi, lib  # noqa: E402
from vehest_can.sim import veh14  # noqa: E402
from vehest_can.sim.mbplant import MbPlant, mb_parameters  # noqa: E402
from vehest_can.sim.session import run_inprocess  # noqa: E402
from vehest_can.systems.ecu import Ecu  # noqa: E402

DT = 0.0005


def scenario(plant: str, **extra) -> veh14.Veh14Scenario:
    doc = {"kind": "tireforce", "name": f"t_{plant}", "duration_s": 3.0, "initial_speed_kmh": 70.0, "plant": plant,
           "driver": {"steer_deg": [[0.0, 0.0], [3.0, 3.0]]}, "road": {"mu": [[0.0, 1.0]]},
           "vehicle": {"drag_area_m2": 0.0}}
    doc.update(extra)  # whole tables
    return veh14.veh14_scenario_from_dict(doc, Path("test.toml"), "tireforce")


@pytest.mark.slow  # numba compiles the model (~7 s) and scipy integrates it
def test_adapter_equals_the_packages_own_integration():
    """Idle actuators, no drive, no drag: the car's truth follows scipy's integration of the package's
    own pure-Python vehicle_dynamics_mb with the same steering input (a 1 deg/s ramp)."""
    from scipy.integrate import solve_ivp
    from vehiclemodels.init_mb import init_mb
    from vehiclemodels.vehicle_dynamics_mb import vehicle_dynamics_mb

    sc = scenario("commonroad_mb")
    car = veh14.Veh14Car(sc)
    truths = np.array([(car.tick(k), car.truth())[1] for k in range(sc.n_steps)])
    p = car.mb.p
    k = np.radians(1.0)  # rad/s of road-wheel angle
    x0 = init_mb([0.0, 0.0, 0.0, 70 / 3.6, 0.0, 0.0, 0.0], p)
    # the adapter steers towards each tick's angle: the rate is k from the second tick on
    def f(u):
        return lambda t, x: vehicle_dynamics_mb(list(x), u, p)

    a = solve_ivp(f([0.0, 0.0]), (0.0, DT), x0, rtol=1e-10, atol=1e-10)
    t_eval = np.arange(1, sc.n_steps) * DT
    b = solve_ivp(f([k, 0.0]), (DT, t_eval[-1]), a.y[:, -1], t_eval=t_eval, rtol=1e-10, atol=1e-10, method="LSODA")
    ref = b.y.T  # state at the start of ticks 1..n-1
    got = truths[1:]
    assert got["r"][-1] > 0.05  # turning left, well away from the start
    for ours, col, sign in (("vx", 3, 1), ("vy", 10, 1), ("r", 5, 1), ("phi", 6, -1), ("p", 7, -1), ("steer", 2, 1)):
        err = np.max(np.abs(got[ours] - sign * ref[:, col]))
        scale = np.max(np.abs(ref[:, col]))
        assert err <= 2e-3 * scale, (ours, err, scale)  # RK4 at the tick vs an adaptive solver


def test_our_plant_and_mb_agree_on_the_big_picture_and_differ_in_detail():
    """The same car data in both plants: a left turn on both, loaded outer wheels, outward roll; MB's
    load transfer larger (its compliances), so they are not the same model."""
    out = {}
    for plant in ("veh14", "commonroad_mb"):
        t = run_inprocess(veh14.Veh14Car(scenario(plant)), Ecu()).truth[-1]
        assert t["r"] > 0 and t["ay"] > 3.0 and t["phi"] > 0
        assert t["fz"][1] > t["fz"][0] and t["fz"][3] > t["fz"][2]  # right wheels outside
        assert np.all(t["spring_defl"][[1, 3]] > t["spring_defl"][[0, 2]])
        out[plant] = (t["fz"][1] - t["fz"][0]) / t["ay"]
    assert out["commonroad_mb"] > 1.05 * out["veh14"]


@pytest.mark.parametrize("plant", ["veh14", "commonroad_mb"])
def test_body_fixed_accelerometer_reads_g_sin_phi(plant):
    """Straight at 50 km/h, a roll moment from the actuators tilts the body: the chassis node's body-fixed
    lateral accelerometer reads g sin(phi) (the body is not accelerating sideways)."""
    import cantools

    from vehest_can.paths import dbc_path

    sc = scenario(plant, initial_speed_kmh=50.0, driver={"steer_deg": [[0.0, 0.0]]},
                  sensors={"accel_gravity": True, "ay_std_m_s2": 0.0, "ay_bias_m_s2": 0.0})
    car = veh14.Veh14Car(sc)
    lib.vh_v14_set_roll_moment(ffi.addressof(car.car, "plant"), 3000.0, 3000.0)
    db = cantools.database.load_file(dbc_path("ch"))
    msg = db.get_message_by_name("CHS_Sensors")
    for k in range(4000):  # 2 s: the roll settles
        frames = car.tick(k)
    t = car.truth()
    data = next(bytes(ffi.buffer(f.data, f.len)) for f in frames if f.id == msg.frame_id)
    ay_meas = msg.decode(data)["LatAccel"]
    assert abs(t["phi"]) > 0.005  # a real tilt (~0.9 deg)
    assert abs(t["ay"]) < 0.15  # nearly: the tilted body drifts a little
    want = t["ay"] * np.cos(t["phi"]) + 9.81 * np.sin(t["phi"])
    assert ay_meas == pytest.approx(want, abs=0.02)
    assert ay_meas == pytest.approx(9.81 * np.sin(t["phi"]), abs=0.15)


@pytest.mark.slow  # two 6 s runs of MB tick by tick
def test_the_tyres_offsets_would_drive_a_relay_limit_cycle():
    """Why MB runs the tyre's offsets at zero: with the package's p_hy1, p_vy1 (multiplied by sign(camber)
    in its formula_lateral) a lane change at 45 km/h leaves the car rolling +-0.5 deg at ~2.5 Hz on a
    straight road with the wheel centred; with the offsets at zero (what the plant runs) the roll dies out."""
    from vehest_can.sim.mbplant import _NCTX, BASE_VEHICLE, _vehicle, flat

    def straight_roll_rate_rms(offsets: bool) -> float:
        sc = scenario("commonroad_mb", duration_s=6.0, initial_speed_kmh=45.0, road={"mu": [[0.0, 0.8]]},
                      driver={"steer_deg": [[0.0, 0.0], [1.0, 0.0], [1.4, 1.5], [2.0, 1.5], [2.6, -1.5],
                                            [3.2, -1.5], [3.6, 0.0]]})
        car = veh14.Veh14Car(sc)
        assert car.mb.p.tire.p_vy1 == 0.0 and car.mb.p.tire.p_hy1 == 0.0
        if offsets:
            base = _vehicle(BASE_VEHICLE).tire
            car.mb.p.tire.p_hy1, car.mb.p.tire.p_vy1 = base.p_hy1, base.p_vy1
            car.mb.ctx[_NCTX:] = flat(car.mb.p)
        p = np.array([(car.tick(k), car.truth()["p"])[1] for k in range(sc.n_steps)])
        return float(np.degrees(np.sqrt(np.mean(p[int(5.0 / DT):] ** 2))))  # 1.4 s after the wheel centred

    assert straight_roll_rate_rms(True) > 2.0   # deg/s: a limit cycle (measured 4.7)
    assert straight_roll_rate_rms(False) < 0.8  # deg/s: dying out (measured 0.25)


def test_mb_refuses_what_it_cannot_model():
    with pytest.raises(ScenarioError, match="split friction"):
        scenario("commonroad_mb", road={"mu_left": [[0.0, 1.0]], "mu_right": [[0.0, 0.5]]})
    with pytest.raises(ScenarioError, match="keeps its own"):
        scenario("commonroad_mb", tyre={"relaxation_length_y_m": 0.3})
    with pytest.raises(ScenarioError, match="unknown plant"):
        scenario("carsim")


def test_mass_reaches_mb():
    base = scenario("commonroad_mb")
    heavy = scenario("commonroad_mb", vehicle={"drag_area_m2": 0.0, "mass_delta_kg": 200.0})
    pb, ph = (mb_parameters(s.plant_params(ffi, lib)) for s in (base, heavy))
    assert ph.m_s == pytest.approx(pb.m_s + 200.0) and ph.m == pytest.approx(pb.m + 200.0)
    assert MbPlant(ph, 10.0).x[3] == 10.0


def test_shipped_scenario_runs_on_mb():
    p = Path(__file__).parents[2] / "firmware_sim/scenarios/tireforce/chassis_relation_70kph.toml"
    doc = tomllib.loads(p.read_text())
    doc["plant"] = "commonroad_mb"
    sc = veh14.veh14_scenario_from_dict(doc, p, "tireforce")
    s = run_inprocess(veh14.Veh14Car(sc, 1.0), Ecu())
    assert np.isfinite(s.truth["fz"]).all() and len(s.frames) > 2000
