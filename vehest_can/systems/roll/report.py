"""The roll system's figures of one session: the ECU's UKF estimates from the bus (VEHEST_RollEst)
against the plant's truth, the actuators' moments, and for an active run its passive twin (the same
scenario in passive mode, in-process: bit for bit what the bus gives, tests/roll/test_roll_bus.py);
the terminal table with the acceptance lines, and the plots like the paper's Fig. 3-6 and 8-15."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ...plotting import Figures, pyplot
from ...sim.report import decode
from ...sim.scenario import DT

#: acceptance: UKF RMS error as a fraction of the peak, roll angle and roll rate
TARGET_PHI, TARGET_P = 0.05, 0.10
#: active vs passive at 72 km/h: peak roll reduced by at least this
TARGET_REDUCTION = 0.50


def chatter(m: np.ndarray, dt: float = DT, f_hz: float = 50.0) -> tuple[float, float]:
    """(total variation [N m], fraction of the signal's energy (mean removed) above f_hz)."""
    tv = float(np.sum(np.abs(np.diff(m))))
    spec = np.abs(np.fft.rfft(m - np.mean(m))) ** 2
    f = np.fft.rfftfreq(len(m), dt)
    tot = spec.sum()
    return tv, float(spec[f > f_hz].sum() / tot) if tot > 0 else 0.0


def _sna_to_nan(name: str, values: dict[str, np.ndarray], scaled: bool = True) -> None:
    """The signals of message `name` sent as their SNA value (the DBC's "SNA" choice: e.g. the UKF's
    estimates while it is INIT) to NaN, in place."""
    from ...bus.frames import message

    for sig in message(name).signals:
        raw = next((k for k, v in (sig.choices or {}).items() if str(v) == "SNA"), None)
        if raw is not None and sig.name in values:
            v = values[sig.name]
            v[v == (raw * sig.scale + sig.offset if scaled else raw)] = np.nan


def estimates(session) -> dict[str, np.ndarray]:
    """The ticks with a VEHEST_RollEst frame and its signals there (NaN where sent as SNA)."""
    est = decode(session, "VEHEST_RollEst")
    _sna_to_nan("VEHEST_RollEst", est)
    k = np.flatnonzero(~np.isnan(est["RollUkf_Health"]))
    return {"tick": k, **{name: v[k] for name, v in est.items()}}


def evaluate(session, arc_limits: tuple[tuple[float, float], ...] | None = None) -> dict[str, Any]:
    """Figures of one session: UKF vs truth (where the estimate is published), peaks, moments."""
    tr = session.truth
    e = estimates(session)
    k = e["tick"]
    on = k[~np.isnan(e["RollEstAngle"])]
    sel = ~np.isnan(e["RollEstAngle"])
    peak_phi, peak_p = float(np.abs(tr["phi"]).max()), float(np.abs(tr["p"]).max())
    err_phi = float(np.sqrt(np.mean((e["RollEstAngle"][sel] - tr["phi"][on]) ** 2))) if on.size else float("nan")
    err_p = float(np.sqrt(np.mean((e["RollEstRate"][sel] - tr["p"][on]) ** 2))) if on.size else float("nan")
    m = tr["m_applied"]
    tv, hf = chatter(m.sum(axis=1))
    rate = np.abs(np.diff(m, axis=0)).max(axis=0) / DT if len(m) > 1 else np.zeros(2)
    out: dict[str, Any] = {
        "peak_roll_deg": float(np.degrees(peak_phi)), "peak_roll_rate_deg_s": float(np.degrees(peak_p)),
        "peak_yaw_rate_deg_s": float(np.degrees(np.abs(tr["r"]).max())),
        "peak_ay_m_s2": float(np.abs(tr["ay"]).max()),
        "ukf_roll_rms_deg": float(np.degrees(err_phi)), "ukf_roll_rate_rms_deg_s": float(np.degrees(err_p)),
        "ukf_roll_rms_pct_of_peak": 100 * err_phi / peak_phi, "ukf_roll_rate_rms_pct_of_peak": 100 * err_p / peak_p,
        "steady_turn_rate_bias_deg_s": steady_turn_bias(session, e),
        "estimates": int(on.size), "ukf_health_ok_pct": 100 * float(np.mean(e["RollUkf_Health"] == 1)) if k.size else 0.0,
        "ukf_resets": int(np.nanmax(e["RollCntReset"])) if k.size else 0,
        "moment_peak_nm": [float(x) for x in np.abs(m).max(axis=0)],
        "moment_rate_peak_nm_s": [float(x) for x in rate],
        "moment_total_variation_nm": tv, "moment_energy_above_50hz_pct": 100 * hf,
        "arc_states": sorted({int(s) for s in tr["arc_state"]}),
    }
    if arc_limits is not None:
        out["limits_respected"] = bool(all(out["moment_peak_nm"][i] <= arc_limits[i][0] + 1e-6 and
                                           out["moment_rate_peak_nm_s"][i] <= arc_limits[i][1] * (1 + 1e-9)
                                           for i in range(2)))
    return out


def steady_turn_bias(session, e: dict | None = None) -> float:
    """The roll-rate estimate's bias in steady turning [deg/s]: |mean(p_hat - p)| over the published
    estimates where the true roll rate stayed within 0.3 deg/s for 0.25 s either side and |a_y| > 2 m/s^2;
    NaN when the run has no such stretch."""
    from numpy.lib.stride_tricks import sliding_window_view

    tr = session.truth
    e = estimates(session) if e is None else e
    ok = ~np.isnan(e["RollEstRate"])
    k, pe = e["tick"][ok], e["RollEstRate"][ok]
    w = 50  # estimate frames (10 ms): 0.5 s
    if len(k) < w:
        return float("nan")
    pt = tr["p"][k]
    calm = np.zeros(len(k), bool)
    still = sliding_window_view(np.abs(pt), w).max(axis=1) < np.radians(0.3)
    calm[w // 2: w // 2 + len(still)] = still
    sel = calm & (np.abs(tr["ay"][k]) > 2.0)
    return float(np.degrees(abs(np.mean(pe[sel] - pt[sel])))) if sel.any() else float("nan")


def vs_passive(active: dict, twin) -> dict:
    """An active session's figures (`active`) against its passive twin's session: :func:`compare`, or
    ``{"passive_diverged_s": t}`` where the twin left its plant's range (no comparison then)."""
    diverged = twin.diverged_s()
    return {"passive_diverged_s": diverged} if diverged is not None else compare(active, evaluate(twin))


def compare(active: dict, passive: dict) -> dict:
    """Active against its passive twin: the peak roll's reduction, the changes the paper notes."""
    return {
        "peak_roll_reduction_pct": 100 * (1 - active["peak_roll_deg"] / passive["peak_roll_deg"]),
        "peak_yaw_rate_change_pct": 100 * (active["peak_yaw_rate_deg_s"] / passive["peak_yaw_rate_deg_s"] - 1),
        "peak_ay_change_pct": 100 * (active["peak_ay_m_s2"] / passive["peak_ay_m_s2"] - 1),
        "passive_peak_roll_deg": passive["peak_roll_deg"],
        "passive_moment_total_variation_nm": passive["moment_total_variation_nm"],
    }


def lines_met(m: dict) -> dict[str, float]:
    """The estimate's acceptance lines of one run, 1.0 met / 0.0 not: roll RMS <= max(5 % of peak,
    0.05 deg), roll rate RMS <= max(10 % of peak, 0.25 deg/s), steady-turn rate bias <= 0.2 deg/s
    (met when the run has no steady turn); ``all`` every one of them."""
    roll = m["ukf_roll_rms_deg"] <= max(100 * TARGET_PHI / 100 * m["peak_roll_deg"], 0.05)
    rate = m["ukf_roll_rate_rms_deg_s"] <= max(TARGET_P * m["peak_roll_rate_deg_s"], 0.25)
    b = m["steady_turn_rate_bias_deg_s"]
    bias = bool(np.isnan(b) or b <= 0.2)
    return {"roll": float(roll), "rate": float(rate), "bias": float(bias), "all": float(roll and rate and bias)}


def acceptance(m: dict) -> list[tuple[str, str, bool]]:
    """(line, figure, pass) of the acceptance lines that apply to one session: the estimate's lines as
    :func:`lines_met` decides them, the actuators' limits, the reduction at 72 km/h."""
    met = lines_met(m)
    b = m["steady_turn_rate_bias_deg_s"]
    rows = [(f"UKF roll RMS <= max({100 * TARGET_PHI:.0f} % of peak, 0.05 deg)",
             f"{m['ukf_roll_rms_pct_of_peak']:.2f} % ({m['ukf_roll_rms_deg']:.4f} deg)", bool(met["roll"])),
            (f"UKF roll rate RMS <= max({100 * TARGET_P:.0f} % of peak, 0.25 deg/s)",
             f"{m['ukf_roll_rate_rms_pct_of_peak']:.2f} % ({m['ukf_roll_rate_rms_deg_s']:.3f} deg/s)", bool(met["rate"])),
            ("steady-turn roll-rate bias <= 0.2 deg/s", "no steady turn" if np.isnan(b) else f"{b:.3f} deg/s",
             bool(met["bias"]))]
    if "limits_respected" in m:
        rows.append(("actuator limits respected", "yes" if m["limits_respected"] else "NO", m["limits_respected"]))
    if "vs_passive" in m and m.get("speed_kmh", 0) >= 70:
        line = f"peak roll reduced >= {100 * TARGET_REDUCTION:.0f} % (72 km/h)"
        red = m["vs_passive"].get("peak_roll_reduction_pct")
        if red is None:
            rows.append((line, f"no passive twin: its plant diverged at {m['vs_passive']['passive_diverged_s']:.3f} s", False))
        else:
            rows.append((line, f"{red:.1f} %", red >= 100 * TARGET_REDUCTION))
    return rows


def acceptance_entries(m: dict) -> list[dict]:
    """The acceptance lines as every system's metrics carry them (line, verdict, detail), which the
    demo's acceptance summary, --check and --junit read."""
    return [{"line": line, "verdict": "pass" if ok else "FAIL", "detail": figure} for line, figure, ok in acceptance(m)]


def table(m: dict) -> str:
    lines = [f"roll: {m['scenario']} ({m['mode']})",
             f"  peak roll {m['peak_roll_deg']:.3f} deg, roll rate {m['peak_roll_rate_deg_s']:.3f} deg/s, "
             f"yaw rate {m['peak_yaw_rate_deg_s']:.2f} deg/s, a_y {m['peak_ay_m_s2']:.2f} m/s^2",
             f"  UKF (float32, ECU, from the bus): roll RMS {m['ukf_roll_rms_deg']:.4f} deg, roll rate RMS "
             f"{m['ukf_roll_rate_rms_deg_s']:.4f} deg/s; health OK {m['ukf_health_ok_pct']:.1f} %, resets {m['ukf_resets']}",
             f"  moments: peak front/rear {m['moment_peak_nm'][0]:.0f} / {m['moment_peak_nm'][1]:.0f} N m, total "
             f"variation {m['moment_total_variation_nm']:.0f} N m, energy above 50 Hz {m['moment_energy_above_50hz_pct']:.3f} %"]
    if "f32_vs_f64_roll_deg" in m:
        lines.append(f"  float32 (ECU) vs double on the same bus samples: max |d roll| {m['f32_vs_f64_roll_deg']:.1e} deg, "
                     f"max |d roll rate| {m['f32_vs_f64_roll_rate_deg_s']:.1e} deg/s; ECU == array API: "
                     f"{'yes' if m['ecu_equals_array_api'] else 'NO'}")
    if "passive_diverged_s" in m.get("vs_passive", {}):
        lines.append(f"  vs passive: none: the passive twin's plant diverged at {m['vs_passive']['passive_diverged_s']:.3f} s "
                     f"(its state not finite, or rolling over, from there on)")
    elif "vs_passive" in m:
        v = m["vs_passive"]
        lines.append(f"  vs passive: peak roll {v['passive_peak_roll_deg']:.3f} -> {m['peak_roll_deg']:.3f} deg "
                     f"({-v['peak_roll_reduction_pct']:+.1f} %), peak yaw rate {v['peak_yaw_rate_change_pct']:+.2f} %, "
                     f"peak a_y {v['peak_ay_change_pct']:+.2f} %")
    for line, fig, ok in acceptance(m):
        lines.append(f"  {'PASS' if ok else 'FAIL'}  {line}: {fig}")
    return "\n".join(lines)


def plants_table(metrics: list[dict]) -> str:
    """The runs on both plants side by side: one row per scenario and plant."""
    head = f"{'scenario':<28}{'plant':<15}{'UKF roll %':>11}{'rate %':>8}{'peak roll deg':>15}{'vs passive':>12}"
    lines = ["== roll on both plants: UKF RMS in % of peak, peak roll reduction by the SMC", head, "-" * len(head)]
    for m in sorted(metrics, key=lambda m: (m["scenario"].split("@")[0], m.get("plant", ""))):
        red = m.get("vs_passive", {}).get("peak_roll_reduction_pct")
        lines.append(f"{m['scenario'].split('@')[0]:<28}{m.get('plant', ''):<15}{m['ukf_roll_rms_pct_of_peak']:>11.2f}"
                     f"{m['ukf_roll_rate_rms_pct_of_peak']:>8.2f}{m['peak_roll_deg']:>15.3f}"
                     + (f"{-red:>+11.1f}%" if red is not None else f"{'-':>12}"))
    return "\n".join(lines)


def plots(session, out_dir: Path, title: str, passive=None, plant: str = "veh14") -> list[Path]:
    """Fig. 3-6: estimated against true roll angle and rate; with a passive twin, Fig. 8-15: control
    moments, yaw rate, roll angle and rate, passive against active."""
    plt = pyplot()
    figs = Figures(out_dir, dpi=100)
    tr = session.truth
    t = np.arange(len(tr)) * DT
    e = estimates(session)
    te = e["tick"] * DT

    def save(fig, ax, what: str, name: str) -> None:
        """Panels over a shared time axis finished alike: the axis label, grid and legend, the title; written."""
        ax[-1].set_xlabel("t [s]")
        for a in ax:
            a.grid(True)
            a.legend()
        fig.suptitle(f"{title}: {what}")
        figs.save(fig, f"{title}_{name}.png")

    fig, ax = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    ax[0].plot(t, np.degrees(tr["phi"]), label=f"truth ({plant} plant)")
    ax[0].plot(te, np.degrees(e["RollEstAngle"]), "--", label="UKF (ECU, from the bus)")
    ax[0].set_ylabel("roll angle [deg]")
    ax[1].plot(t, np.degrees(tr["p"]), label="truth")
    ax[1].plot(te, np.degrees(e["RollEstRate"]), "--", label="UKF")
    ax[1].set_ylabel("roll rate [deg/s]")
    save(fig, ax, "roll estimate (cf. seed 003 Fig. 3-6)", "estimate")
    if passive is not None:
        tp = passive.truth
        fig, ax = plt.subplots(4, 1, figsize=(8, 10), sharex=True)
        ax[0].plot(t, tr["m_applied"][:, 0], label="front, active")
        ax[0].plot(t, tr["m_applied"][:, 1], label="rear, active")
        ax[0].set_ylabel("roll moment [N m]")
        for a, key, unit in ((ax[1], "r", "yaw rate [deg/s]"), (ax[2], "phi", "roll angle [deg]"),
                             (ax[3], "p", "roll rate [deg/s]")):
            a.plot(t, np.degrees(tp[key]), label="passive")
            a.plot(t, np.degrees(tr[key]), label="active")
            a.set_ylabel(unit)
        save(fig, ax, "passive against active (cf. seed 003 Fig. 8-15)", "passive_vs_active")
    return figs.paths


def _by_tick(session, name: str, n: int, scaling: bool = True) -> dict[str, np.ndarray]:
    from ...bus.frames import message

    msg = message(name)
    out = {s.name: np.full(n, np.nan) for s in msg.signals}
    sel = session.frames["id"] == msg.frame_id
    for f, k in zip(session.frames[sel], session.frame_tick[sel]):
        for key, v in msg.decode(bytes(f["data"][: f["len"]]), decode_choices=False, scaling=scaling).items():
            out[key][k] = v
    return out


def bus_samples(session, car=None):
    """What the ECU's UKF took from the bus, decoded: (its parameters as ``vh_roll_params_t *``, u (n, NU),
    z (n, NZ), the ticks of its steps). `car`: the car the ECU was calibrated for (a
    :class:`~vehest_can.carfile.CarFile`; None: the paper's)."""
    from ...native import ffi as nffi
    from ...native import lib as nlib
    from . import api as rn

    cfg = nffi.new("vh_roll_app_config_t *")
    nlib.vh_roll_app_config_default(cfg)
    if car is not None:
        rn.write_car(cfg, car)
    over = {name: (list(getattr(cfg.ukf, name)) if f.type.kind == "array" else getattr(cfg.ukf, name))
            for name, f in nffi.typeof(cfg.ukf).fields}
    prm = rn.make_params(**over)
    n = len(session.truth)
    sens = _by_tick(session, "ROLL_Sensors", n)
    yaw = _by_tick(session, "ROLL_YawRate", n)
    act = _by_tick(session, "ROLL_ActuatorStatus", n)
    chs = _by_tick(session, "CHS_Sensors", n)
    steps = np.flatnonzero(~np.isnan(sens["RollLatAccel"]))
    names = ["RollLatAccel"] + [f"{g}{w}" for g in ("WheelVertAccel", "TyreDefl", "SuspDefl") for w in ("FL", "FR", "RL", "RR")]
    z = np.column_stack([sens[s][steps] for s in names] + [yaw["RollYawRate"][steps]])
    w = [chs[f"WheelSpeed{x}"][steps] for x in ("FL", "FR", "RL", "RR")]
    vx = float(cfg.rw) * (((w[0] + w[1]) + w[2]) + w[3]) / 4.0   # as the ECU sums them
    u = np.column_stack([chs["SteerAngle"][steps], vx, act["AppliedMomentF"][steps], act["AppliedMomentR"][steps]])
    return prm, u, z, steps


def rerun(session, car=None) -> dict[str, Any]:
    """The ECU's float32 UKF once more, through the array API (in ``vehest_can._native``) on the samples
    decoded from the bus, and the double build on the same: whether the published estimates equal the
    array API's at the DBC's resolution (bit for bit), and how far float32 is from double. Assumes a
    clean run (every measurement valid at every step), as the shipped cases are. `car`: the car the ECU was
    calibrated for (a :class:`~vehest_can.carfile.CarFile`; None: the paper's)."""
    from . import api as rn

    prm, u, z, steps = bus_samples(session, car)
    n = len(session.truth)
    x32, _, h32 = rn.Ukf(prm, "f32").run(u, z)
    x64, _, _ = rn.Ukf(prm, "f64").run(u, z)
    raw = _by_tick(session, "VEHEST_RollEst", n, scaling=False)
    est_ticks = np.flatnonzero(~np.isnan(raw["RollUkf_Health"]))
    row = np.searchsorted(steps, est_ticks)
    _sna_to_nan("VEHEST_RollEst", raw, scaled=False)
    from ...bus.frames import message

    sig = message("VEHEST_RollEst").get_signal_by_name
    init = h32[row] == rn.lib.VH_ROLL_H_INIT            # SNA while INIT (not converged), the value otherwise
    same = all(np.array_equal(np.isnan(raw[s][est_ticks]), init) and
               np.array_equal(np.floor(x32[row[~init], i].astype(np.float64) / sig(s).scale + 0.5),
                              raw[s][est_ticks[~init]])
               for i, s in ((4, "RollEstAngle"), (5, "RollEstRate")))
    return {"ecu_equals_array_api": bool(same), "steps": int(len(steps)),
            "f32_vs_f64_roll_deg": float(np.degrees(np.abs(x32[:, 4] - x64[:, 4]).max())),
            "f32_vs_f64_roll_rate_deg_s": float(np.degrees(np.abs(x32[:, 5] - x64[:, 5]).max()))}
