"""The robust model as UKF and as EKF on the samples the ECU decoded from the bus (docs/roll.md, "UKF
against EKF on the robust model"), on a run the tuning did not see, on both plants."""
import pytest

from vehest_can.carfile import car_of
from vehest_can.sim.session import run_inprocess
from vehest_can.systems.ecu import Ecu, EcuConfig
from vehest_can.systems.roll import evaluate as ev
from vehest_can.systems.roll.scenario import RollCar, roll_scenario_from_dict


def lane_change(plant: str) -> dict:
    return {"kind": "roll", "name": "lane_change_100kph_p250", "duration_s": 3.0, "seed": 11,
            "initial_speed_kmh": 100.0, "plant": plant,
            "driver": {"steer_deg": [[0, 0], [1.0, 0], [1.4, 2.0], [2.2, -2.0], [2.6, 0]]},
            "road": {"mu": [[0.0, 1.0]]}, "vehicle": {"mass_delta_kg": 250.0},
            "control": {"mode": [[0.0, "passive"]]}}


@pytest.mark.parametrize("plant", ["veh14", pytest.param("commonroad_mb", marks=pytest.mark.slow)])
def test_ukf_and_ekf_agree_and_our_plant_is_consistent(plant):
    sc = roll_scenario_from_dict(lane_change(plant))
    session = run_inprocess(RollCar(sc), Ecu(EcuConfig(car=car_of(sc))))
    r = ev.filters_on_bus(session, car_of(sc))
    print(f"\n{plant}: {r}")
    for key in ("roll_pct", "rate_pct"):
        assert abs(r["ukf"][key] - r["ekf"][key]) < 0.05, (key, r)
    assert r["ukf"]["roll_pct"] < 5.0 and r["ukf"]["rate_pct"] < 10.0, r
    if plant == "veh14":  # the model's own plant: the NIS says the covariance is honest (R conservative)
        assert 0.2 < r["ukf"]["nis_per_measurement"] < 1.5, r
