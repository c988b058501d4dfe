"""The roll UKF against the 14-DOF plant's truth on seed 003's cases (steer ramp to 5 deg at 36
and 72 km/h, level road): roll angle RMS error <= 5 % of the peak roll, roll rate RMS error
<= 10 % of the peak roll rate, in both builds; float32 vs double reported."""
import numpy as np
import pytest

from vehest_can.systems.roll import api as rn
from vehest_can.systems.roll import evaluate as ev


@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("speed", [36.0, 72.0])
def test_ukf_tracks_the_plant_truth(speed, seed):
    res = ev.evaluate_case(speed, seed=seed)
    for line in res.lines():
        print(line)
    for prec in rn.PRECISIONS:
        assert res.rms_phi[prec] <= 0.05 * res.peak_phi
        assert res.rms_p[prec] <= 0.10 * res.peak_p
        assert res.resets[prec] == 0
    assert res.f32_vs_f64_phi < 1e-5


def test_the_72_kmh_case_is_near_the_friction_limit():
    truth = ev.run_plant(ev.paper_case(72.0))
    assert np.abs(truth["ay"]).max() > 0.8 * 9.81
