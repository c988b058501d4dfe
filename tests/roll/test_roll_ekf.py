"""The issue asks whether the UKF beats an EKF on this problem (the paper argues it does): both on
the same model and tuning, the paper's cases and harder manoeuvres of ours. Figures printed; the
test holds both to the acceptance targets where the UKF meets them, and does not assume a winner."""
import pytest

from vehest_can.systems.roll import evaluate as ev

pytestmark = pytest.mark.slow

CASES = {
    "paper 36 km/h": ev.paper_case(36.0),
    "paper 72 km/h": ev.paper_case(72.0),
    "sine 6 deg 0.7 Hz 72 km/h": ev.sine_case(),
    "sine 6 deg 0.7 Hz 72 km/h, road mu 0.7 (filter assumes 1)": ev.sine_case(mu=0.7),
}


@pytest.mark.parametrize("name", list(CASES))
def test_ukf_and_ekf_on_the_same_model(name):
    r = ev.ukf_vs_ekf(CASES[name])
    print(f"{name}: peak a_y {r['peak_ay']:.2f} m/s^2; UKF roll {100 * r['ukf'][0]:.3f} %, rate "
          f"{100 * r['ukf'][1]:.2f} %; EKF roll {100 * r['ekf'][0]:.3f} %, rate {100 * r['ekf'][1]:.2f} % (of peak)")
    for f in ("ukf", "ekf"):
        assert r[f][0] <= 0.05 and r[f][1] <= 0.10


@pytest.mark.xfail(strict=True, reason="known shortfall: on a road of mu 0.7 with the filter's tyre at "
                   "mu 1, the paper's slow ramp gives a roll-rate RMS error of ~14 % of its (small) peak")
def test_ramp_on_a_lower_friction_road_than_the_filter_assumes():
    doc = ev.paper_case(72.0)
    doc["road"] = {"mu": [[0.0, 0.7]]}
    r = ev.ukf_vs_ekf(doc)
    print(f"ramp 5 deg, 72 km/h, mu 0.7: UKF roll {100 * r['ukf'][0]:.3f} %, rate {100 * r['ukf'][1]:.2f} %")
    assert r["ukf"][1] <= 0.10
