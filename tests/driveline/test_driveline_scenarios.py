"""The driveline KF on the shipped scenarios against the plant truth and the configured sensor noise."""
import numpy as np
import pytest

from vehest_can.native import ffi, lib
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.sim.report import decode
from vehest_can.sim.session import run_inprocess
from vehest_can.systems.driveline import reference as dkf_ref
from vehest_can.systems.driveline import report
from vehest_can.systems.driveline.api import DkfConfig, DrivelineKF
from vehest_can.systems.driveline.scenario import driveline_scenario_dir, load_driveline_scenario
from vehest_can.systems.ecu import Ecu

DRIVELINE = sorted(driveline_scenario_dir().glob("*.toml"))


@pytest.fixture(scope="module", params=DRIVELINE, ids=lambda p: p.stem)
def scenario(request):
    return load_driveline_scenario(request.param)


@pytest.fixture(scope="module")
def session(scenario):
    return run_inprocess(powertrain_car(scenario), Ecu())


def residual_fits_the_noise(rms_meas_minus_est: float, rms_est_minus_truth: float, sigma: float) -> bool:
    """A filter that weighs the torque sensor as it is configured leaves a posterior residual (meas -
    est) a little below the sensor noise: at most sigma, and at least 85 % of sqrt(sigma^2 - e^2), e
    the estimate's own error (the optimal filter's R - HPH'). A filter that follows the sensor (0), or
    ignores it (well above sigma), fails."""
    return 0.85 * np.sqrt(max(sigma**2 - rms_est_minus_truth**2, 0.0)) <= rms_meas_minus_est <= sigma


def test_the_residual_check_rejects_a_filter_that_follows_or_ignores_the_sensor():
    assert residual_fits_the_noise(6.7, 2.7, 7.8)
    assert not residual_fits_the_noise(0.3, 0.3, 7.8)    # est = meas: the noise passed through
    assert not residual_fits_the_noise(16.0, 16.0, 7.8)  # the sensor ignored


def test_estimates_against_truth_meet_the_targets(scenario, session):
    m = {s["measurement_set"]: s for s in report.driveline_metrics(session)["sets"]}
    t, s = m["speeds+torque"], m["speeds"]
    sigma = float(scenario.node_config(ffi, lib).noise_std[3])  # the torque sensor's configured noise
    assert t["sensor_noise_rms_nm"] == pytest.approx(sigma, rel=0.05)  # the node adds what it is told
    assert t["rms_est_minus_truth_nm"] <= 0.5 * sigma
    assert s["rms_est_minus_truth_nm"] <= 30.0
    assert residual_fits_the_noise(t["rms_meas_minus_est_nm"], t["rms_est_minus_truth_nm"], sigma), t
    # the same check on the speeds-only filter, which does not see the torque sensor, fails
    assert not residual_fits_the_noise(s["rms_meas_minus_est_nm"], s["rms_est_minus_truth_nm"], sigma), s
    # without the turbine-torque input the speeds-only estimate is badly biased (paper, Fig. 12)
    assert abs(s["no_input_mean_bias_nm"]) > 5 * s["rms_est_minus_truth_nm"]
    assert t["valid_fraction"] > 0.99 and s["valid_fraction"] > 0.85  # speeds-only is INIT for its first 1 s


def test_c_filter_equals_numpy_reference_over_a_full_scenario(session):
    """The ECU's C filter (array API) against the independent numpy implementation on the
    scenario's measured data: 1e-9 relative (normwise per state)."""
    sens = decode(session, "DLS_Sensors")
    est = decode(session, "VEHEST_DrivelineEst")
    z = np.c_[sens["OutShaftSpeed"], 0.5 * (sens["WheelSpeedL"] + sens["WheelSpeedR"]), sens["ShaftTorque"]]
    u = est["TurbineTorque"]
    for meas in ("speeds+torque", "speeds"):
        cfg = DkfConfig.default(meas)
        x_c = DrivelineKF(cfg).run(u, z).x
        x_ref, _ = dkf_ref.run(cfg, u, z)
        rel = np.abs(x_c - x_ref).max(axis=0) / np.abs(x_ref).max(axis=0)
        assert rel.max() < 1e-9, (meas, rel)


def test_ecu_estimates_match_the_array_api_to_frame_resolution(session):
    """The ECU tick (float32) and the Python array API (double) share one C filter source: fed the
    same decoded inputs, the array API reproduces the published T_o to within the frame's 0.25 Nm
    quantisation, the effect of the 0.02 Nm quantisation of the published input and the float32
    bound below."""
    sens = decode(session, "DLS_Sensors")
    est = decode(session, "VEHEST_DrivelineEst")
    z = np.c_[sens["OutShaftSpeed"], 0.5 * (sens["WheelSpeedL"] + sens["WheelSpeedR"]), sens["ShaftTorque"]]
    x = DrivelineKF(DkfConfig.default("speeds+torque")).run(est["TurbineTorque"], z).x
    assert np.max(np.abs(x[:, 2] - est["DkfT_ShaftTorque"])) < 1.0


def run_f32(cfg: DkfConfig, u: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, int]:
    """The ECU's float32 build of the filter (vh_dkf_f32_*, the same step source) over arrays."""
    f = ffi.new("vh_dkf_f32_t *")
    assert lib.vh_dkf_f32_init(f, cfg.to_c()) == lib.VH_OK
    u32, z32 = np.ascontiguousarray(u, np.float32), np.ascontiguousarray(z, np.float32)
    x = np.empty((len(u), 4), np.float32)
    resets = lib.vh_dkf_f32_run(f, len(u), ffi.cast("float *", ffi.from_buffer(u32)), ffi.cast("float *", ffi.from_buffer(z32)),
                                ffi.NULL, ffi.cast("float *", ffi.from_buffer(x)), ffi.NULL, ffi.NULL)
    return x.astype(np.float64), int(resets)


#: float32 against double, the documented bound (docs/firmware.md, "The cost of a tick"): T_o at most
#: 0.1 Nm apart and 0.01 % of the peak torque RMS (measured: 0.02 Nm, 0.0022 %), the error against the
#: truth within 1 % of the double's (measured: 0.05 %), no reset in either
F32_MAX_NM, F32_RMS_PCT_PEAK, F32_TRUTH_REL = 0.1, 0.01, 0.01


def test_float32_filter_the_ecu_runs_is_within_its_bound_of_double(session):
    sens = decode(session, "DLS_Sensors")
    est = decode(session, "VEHEST_DrivelineEst")
    z = np.c_[sens["OutShaftSpeed"], 0.5 * (sens["WheelSpeedL"] + sens["WheelSpeedR"]), sens["ShaftTorque"]]
    u = est["TurbineTorque"]
    ok = np.all(np.isfinite(z), axis=1) & np.isfinite(u)
    skip = int(report.SETTLE_S / 0.0005)
    to = session.truth["to"][ok]
    peak = np.max(np.abs(to))
    for meas in ("speeds+torque", "speeds"):
        cfg = DkfConfig.default(meas)
        d = DrivelineKF(cfg).run(u[ok], z[ok])
        x32, resets = run_f32(cfg, u[ok], z[ok])
        diff = (x32[:, 2] - d.x[:, 2])[skip:]
        assert resets == 0 and d.resets == 0
        assert np.max(np.abs(diff)) <= F32_MAX_NM, meas
        assert 100 * np.sqrt(np.mean(diff ** 2)) / peak <= F32_RMS_PCT_PEAK, meas
        e64 = np.sqrt(np.mean((d.x[skip:, 2] - to[skip:]) ** 2))
        e32 = np.sqrt(np.mean((x32[skip:, 2] - to[skip:]) ** 2))
        assert abs(e32 - e64) <= F32_TRUTH_REL * e64, meas
    # and the ECU (float32 in the tick) publishes what its build computes, to the frame's resolution
    x32, _ = run_f32(DkfConfig.default("speeds+torque"), u, z)
    assert np.max(np.abs(x32[:, 2] - est["DkfT_ShaftTorque"])[np.isfinite(est["DkfT_ShaftTorque"])]) < 1.0
