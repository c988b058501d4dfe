"""Active roll control on CommonRoad's multi-body plant (docs/roll.md, "The robust law"): the
actuator's moment as the adapter applies it (open loop, both plants), and a held-out closed-loop run
(the ECU's float32 robust UKF + robust SMC over the bus, in-process) against its passive twin."""
import numpy as np
import pytest

pytest.importorskip("vehiclemodels")
pytest.importorskip("numba")

from vehest_can.carfile import car_of  # noqa: E402
from vehest_can.native import ffi, lib  # noqa: E402
from vehest_can.sim.session import run_inprocess  # noqa: E402
from vehest_can.systems.ecu import Ecu, EcuConfig  # noqa: E402
from vehest_can.systems.roll import api as rn  # noqa: E402
from vehest_can.systems.roll import report  # noqa: E402
from vehest_can.systems.roll.scenario import RollCar, roll_scenario_from_dict  # noqa: E402

PLANTS = ("veh14", "commonroad_mb")


def _doc(plant, steer, kmh=72.0, secs=6.0, dm=0.0, mu=1.0, seed=7):
    return {"kind": "roll", "name": "t", "duration_s": secs, "seed": seed, "initial_speed_kmh": kmh,
            "plant": plant, "driver": {"steer_deg": steer}, "road": {"mu": [[0.0, mu]]},
            "vehicle": {"drag_area_m2": 0.0, "mass_delta_kg": dm}, "control": {"mode": [[0.0, "active"]]}}


def _open_loop_roll(plant, m_total, secs=4.0):
    """Straight ahead, a constant commanded moment (split as the SMC splits it, no ECU on the bus: the
    roll node never hears a command, so the plant keeps this one); the roll at the end."""
    car = RollCar(roll_scenario_from_dict(_doc(plant, [[0.0, 0.0]], secs=secs)))
    sp = rn.default_smc_params()
    lib.vh_v14_set_roll_moment(ffi.addressof(car.car, "plant"), sp.front_share * m_total,
                               (1 - sp.front_share) * m_total)
    buf = ffi.new("vh_frame_t[64]")
    phi = np.zeros(car.n)
    for k in range(car.n):
        lib.vh_car_tick(car.c, k, buf, 64)
        phi[k] = car.car.plant.truth.phi
    return phi, (car.car.plant.arc.m[0], car.car.plant.arc.m[1])


@pytest.mark.slow
@pytest.mark.parametrize("plant", PLANTS)
def test_a_constant_moment_rolls_both_plants_as_the_model_says(plant):
    """Sign (+ lifts the left), units and application (body, reaction on the axle): the steady roll
    per moment is eta / (k_phi - ms g e), the actuator turning the body against the suspension alone.
    (MB's roll mode rings lightly damped: the mean over the last 2 s.)"""
    m = 2000.0
    phi0, _ = _open_loop_roll(plant, 0.0)
    phi1, applied = _open_loop_roll(plant, m)
    assert sum(applied) == pytest.approx(m, rel=1e-6)
    d = float(np.mean(phi1[-4000:] - phi0[-4000:]))
    prm = rn.default_params()
    prm.variant = lib.VH_ROLL_V_ROBUST
    sp = rn.default_smc_params(prm)
    want = sp.eta * m / (sp.kphi - sp.ms_e * 9.81)
    print(f"{plant}: {m:.0f} N m -> {np.degrees(d):.3f} deg (model {np.degrees(want):.3f} deg)")
    assert d == pytest.approx(want, rel=0.1)


def _reduction(doc):
    sc = roll_scenario_from_dict(doc)
    cfg = EcuConfig(car=car_of(sc), systems={"roll": {"variant": "robust"}})
    act = run_inprocess(RollCar(sc), Ecu(cfg))
    pas = run_inprocess(RollCar(sc.with_mode("passive")), Ecu(EcuConfig(car=car_of(sc))))
    arc = sc.arc_params(ffi, lib)
    limits = tuple((float(arc[i].m_max), float(arc[i].rate_max)) for i in range(2))
    m, mp = report.evaluate(act, limits), report.evaluate(pas, limits)
    return 100 * (1 - m["peak_roll_deg"] / mp["peak_roll_deg"]), m


@pytest.mark.slow
def test_active_control_halves_the_roll_on_mb_in_a_held_out_lane_change():
    """A run no constant was chosen on: a lane change at 100 km/h, +250 kg, mu 0.9, on MB. The robust
    law holds it (>= 50 % less peak roll than the passive twin, no filter reset, limits respected). (The
    paper's law, the baseline, holds this one too, 60 %; on MB it is worse than passive in 7 of the 13
    runs of docs/roll.md's table.)"""
    doc = _doc("commonroad_mb", [[0, 0], [1.0, 0], [1.4, 2.0], [2.2, -2.0], [2.6, 0]], kmh=100.0, dm=250.0, mu=0.9)
    red, m = _reduction(doc)
    print(f"robust law on MB: peak roll {red:.1f} % below passive, resets {m['ukf_resets']}")
    assert red >= 50.0 and m["ukf_resets"] == 0 and m["limits_respected"]
