"""Tire-force report (seed 000): the three estimators against the 14-DOF plant's truth.

The tyre-force scenario runs offline (plant and sensor node tick by tick,
:meth:`~vehest_can.sim.veh14.Veh14Scenario.run_with_frames`); the ``CHS_Sensors`` frames are decoded
with cantools (the DBC is the only description of the bytes, SNA and qualifiers included) and fed to
SKFMEC (double), SKFMEC (fixed point, the ECU's) and the plain EKF (:mod:`vehest_can.systems.tireforce.api`).
What comes out: a metrics dict (JSON), the paper's figures as PNGs (Fig. 3-4 relation check,
Fig. 5-6 inner and outer front lateral force, plus per-tire errors) and a terminal table with the
acceptance lines and an honest verdict on each.

``vehest-can study tireforce.report [SCENARIO ...] -o DIR``.
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import ConfigError, ScenarioError
from ...plotting import Figures, pyplot
from ...sim.report import verdict_word, write_metrics
from ...sim.scenario import DT
from . import api as tf
from .adaptive import ADAPTIVE, AdaptiveConfig, AdaptiveRun, AdaptiveSkfmec

WHEELS = tf.WHEELS
AXLES = ("front", "rear")
SETTLE_S = 0.2
TARGET_TIRE_PCT = 10.0        # acceptance: per-tire RMS error <= 10 % of the tire's peak |Fy|
TARGET_FIXED_PCT = 0.5        # acceptance: fixed vs double <= 0.5 % of peak per tire, no saturation
TARGET_MASS_PCT = 5.0         # acceptance: SKFMEC-A's final mass estimate within 5 % of the truth
AY_BAND_G = (0.1, 0.5)        # the paper: the relations hold below ~0.5 g; below 0.1 g the ratios are noise
G = 9.81

#: CHS_Sensors signal -> (Inputs field, column or None, mask bit)
_INPUT_SIGNALS = {
    "LongAccel": ("ax", None, "VH_SKF_Y_AX"),
    "LatAccel": ("ay", None, "VH_SKF_Y_AY"),
    "YawRate": ("r", None, "VH_SKF_Y_R"),
    "RollRate": ("p", None, "VH_SKF_Y_P"),
    "SteerAngle": ("delta", None, "VH_SKF_U_VALID"),
    **{f"WheelSpeed{w}": ("omega", i, "VH_SKF_U_VALID") for i, w in enumerate(WHEELS)},
    **{f"WheelTorque{w}": ("torque", i, "VH_SKF_U_VALID") for i, w in enumerate(WHEELS)},
}


# ---- decoding ------------------------------------------------------------------------------

@dataclass
class DecodedInputs:
    """Estimator inputs decoded from ``CHS_Sensors`` frames, one row per frame.

    ``inputs`` holds the physical values with **NaN** wherever a signal is not available (SNA), its
    qualifier is INVALID, or the whole frame failed its E2E check: nothing invalid becomes a number.
    ``mask`` is the per-row validity mask of ``TireForceKF.run`` / ``TireForceFixed.run``
    (``VH_SKF_Y_AX|Y_AY|Y_R|Y_P`` per measurement, ``VH_SKF_U_VALID`` for steer, wheel speeds and
    torques together). Feed the filters :meth:`for_filter` with ``mask``; passing ``inputs`` with
    NaN instead also works but empties the whole row (the filters' rule for a non-finite input).
    """

    inputs: tf.Inputs
    mask: np.ndarray              # (n,) uint8
    invalid: dict[str, int]       # samples per signal that were SNA or qualifier-INVALID
    e2e_rejected: int = 0         # frames refused by the E2E check (wrong CRC, repeated counter, short)
    #: (n, 4) the springs' deflections [m] SKFMEC-A may use at each row (``CHS_RideHeight``, held
    #: between its frames as the ECU holds them); a row of NaN where they are not usable (never
    #: heard, timed out, a channel invalid). None: no CHS_RideHeight in the frames at all.
    ride: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.mask)

    def for_filter(self) -> tf.Inputs:
        """``inputs`` with each NaN replaced by 0. Only allowed because every NaN's mask bit is clear
        (checked), and the filters do not read a value whose bit is clear."""
        out = {}
        bits = self._bits()
        for f in fields(tf.Inputs):
            a = np.array(getattr(self.inputs, f.name), dtype=np.float64)
            bad = ~np.isfinite(a)
            rows = bad.any(axis=1) if a.ndim == 2 else bad
            if np.any(self.mask[rows] & bits[f.name]):
                raise ConfigError(f"{f.name}: non-finite value in a row whose mask marks it valid")
            a[bad] = 0.0
            out[f.name] = a
        return tf.Inputs(**out)

    @staticmethod
    def _bits() -> dict[str, int]:
        from ...native import lib

        out: dict[str, int] = {}
        for field, _, bit in _INPUT_SIGNALS.values():
            out[field] = out.get(field, 0) | int(getattr(lib, bit))
        return out


def _chs_message(name: str = "CHS_Sensors"):
    from ...bus.frames import database

    return database("ch").get_message_by_name(name)


RIDE_SIGNALS = tuple(f"SpringDefl{w}" for w in WHEELS)


def _ride_heights(events: list[tuple[int, bytes]], n: int, e2e: bool) -> tuple[np.ndarray | None, int]:
    """The ``CHS_RideHeight`` frames as the ECU uses them (vh_tireforce_app.c): (row, payload) in the
    order received, each at the row of the ``CHS_Sensors`` frame of its tick. Returns ((n, 4) the
    deflections usable at each row, NaN elsewhere; None without any frame) and the frames E2E refused.
    Usable: the last good frame had all four channels valid and is younger than its timeout."""
    from ...bus.frames import E2E_USABLE, e2e_check, e2e_config
    from ...native import ffi, lib

    if not events:
        return None, 0
    msg = _chs_message("CHS_RideHeight")
    attrs = msg.dbc.attributes if msg.dbc else {}
    timeout = int(attrs["RxTimeoutCycles"].value) * int(round(msg.cycle_time * 1e-3 / DT))  # in ticks
    sigs = [msg.get_signal_by_name(s) for s in RIDE_SIGNALS]
    rx = ffi.new("vh_e2e_rx_t *")
    lib.vh_e2e_rx_init(rx)
    cfg = e2e_config(msg)
    out = np.full((n, 4), np.nan)
    rejected = 0
    last_row, value = None, None
    events = sorted(events, key=lambda e: e[0])  # stable: arrival order within a row
    k = 0
    for r in range(n):
        while k < len(events) and events[k][0] <= r:
            p = events[k][1]
            k += 1
            if len(p) != msg.length or (e2e and e2e_check(cfg, rx, p) not in E2E_USABLE):
                rejected += 1
                continue
            d = msg.decode(p, decode_choices=False, scaling=False)
            ok = all(d[f"Qf_{s.name}"] == 1 and d[s.name] != _sna_raw(s) for s in sigs)
            last_row = r
            value = np.array([d[s.name] * s.scale + s.offset for s in sigs]) if ok else None
        if last_row is not None and value is not None and r - last_row < timeout:
            out[r] = value
    return out, rejected


def _sna_raw(sig) -> int | None:
    for raw, name in (sig.choices or {}).items():
        if str(name) == "SNA":
            return int(raw)
    return None


def _assemble(values: dict[str, np.ndarray], qualifiers: dict[str, np.ndarray], frame_ok: np.ndarray,
              e2e_rejected: int) -> DecodedInputs:
    from ...native import lib

    n = len(frame_ok)
    cols: dict[str, np.ndarray] = {"omega": np.empty((n, 4)), "torque": np.empty((n, 4))}
    mask = np.full(n, int(lib.VH_SKF_ALL_VALID), dtype=np.uint8)
    invalid = {}
    for sig, (field, col, bit) in _INPUT_SIGNALS.items():
        v = np.asarray(values[sig], dtype=np.float64).copy()
        bad = ~np.isfinite(v) | (qualifiers[sig] == 0)
        invalid[sig] = int(np.count_nonzero(bad & frame_ok))
        bad |= ~frame_ok
        v[bad] = np.nan
        mask[bad] &= np.uint8(~int(getattr(lib, bit)) & 0xFF)
        if col is None:
            cols[field] = v
        else:
            cols[field][:, col] = v
    return DecodedInputs(tf.Inputs(**cols), mask, invalid, e2e_rejected)


def decode_inputs(frames, *, e2e: bool = True) -> DecodedInputs:
    """The chassis sensor node's frames -> :class:`DecodedInputs`: ``can.Message`` objects, (frame ID,
    payload) pairs or bare payloads (bytes, taken as ``CHS_Sensors``), in the order received.

    One row per ``CHS_Sensors`` frame; ``CHS_RideHeight`` frames give ``ride`` (held between them, as
    the ECU holds them); other IDs and extended-ID frames are skipped (a bus log may hold anything).
    With ``e2e`` every frame is checked by the firmware's own E2E check in order; a wrong CRC, a
    repeated counter or a short frame makes the whole row invalid (a skipped counter is frames lost
    on the way: the data is used, as the ECU does)."""
    from ...bus.frames import E2E_USABLE, authentic_data, e2e_check, e2e_config
    from ...native import ffi, lib

    msg = _chs_message()
    ride_id = _chs_message("CHS_RideHeight").frame_id
    payloads: list[bytes] = []
    ride_events: list[tuple[int, bytes]] = []
    for f in frames:
        if isinstance(f, (bytes, bytearray, memoryview)):
            fid, data = msg.frame_id, bytes(f)
        elif isinstance(f, tuple) and len(f) == 2:
            fid, data = int(f[0]), bytes(f[1])
        elif hasattr(f, "arbitration_id"):
            if f.is_extended_id:
                continue
            fid, data = f.arbitration_id, bytes(f.data)
        else:
            raise ConfigError(f"decode_inputs: expected payload bytes, (ID, payload) or can.Message, "
                              f"not {type(f).__name__}")
        if fid in (msg.frame_id, ride_id):
            data = authentic_data(fid, data)  # a SecOC tail, if on, is not the E2E CRC's (zeros there)
        if fid == msg.frame_id:
            payloads.append(data)
        elif fid == ride_id:
            ride_events.append((max(len(payloads) - 1, 0), data))
    n = len(payloads)
    sigs = [s for s in msg.signals if s.name in _INPUT_SIGNALS]
    raw = {s.name: np.zeros(n) for s in sigs}
    qual = {s: np.zeros(n, dtype=np.int64) for s in _INPUT_SIGNALS}
    ok = np.ones(n, dtype=bool)
    rejected = 0
    rx = ffi.new("vh_e2e_rx_t *")
    lib.vh_e2e_rx_init(rx)
    cfg = e2e_config(msg)
    for k, p in enumerate(payloads):
        if e2e and e2e_check(cfg, rx, p) not in E2E_USABLE:
            ok[k] = False
            rejected += 1
            continue
        if len(p) < msg.length:
            ok[k] = False
            rejected += 1
            continue
        d = msg.decode(p, decode_choices=False, scaling=False)
        for s in sigs:
            raw[s.name][k] = d[s.name]
            qual[s.name][k] = d[f"Qf_{s.name}"]
    values = {}
    for s in sigs:
        v = raw[s.name] * s.scale + s.offset
        sna = _sna_raw(s)
        if sna is not None:
            v[raw[s.name] == sna] = np.nan
        values[s.name] = v
    dec = _assemble(values, qual, ok, rejected)
    dec.ride, ride_rejected = _ride_heights(ride_events, n, e2e)
    dec.e2e_rejected += ride_rejected
    return dec


def _qualifier(q) -> int:
    """A decoded Qf_ signal: 1 (VALID) or 0; a choice name (NamedSignalValue, str) by its name."""
    if isinstance(q, (int, np.integer)) and not isinstance(q, bool):
        return int(q)
    return 1 if str(getattr(q, "name", q)) == "VALID" else 0


def decode_signals(rows: list[dict]) -> DecodedInputs:
    """Already decoded ``CHS_Sensors`` signal dicts (cantools ``decode``, physical values, with or
    without choices) -> :class:`DecodedInputs`. SNA comes as the choice name or as its physical
    value; every input signal and its ``Qf_`` qualifier must be present."""
    msg = _chs_message()
    n = len(rows)
    values = {s: np.empty(n) for s in _INPUT_SIGNALS}
    qual = {s: np.empty(n, dtype=np.int64) for s in _INPUT_SIGNALS}
    sna_phys = {}
    for s in msg.signals:
        if s.name in _INPUT_SIGNALS:
            r = _sna_raw(s)
            sna_phys[s.name] = (None if r is None else r * s.scale + s.offset, s.scale)
    for k, row in enumerate(rows):
        for s in _INPUT_SIGNALS:
            if s not in row or f"Qf_{s}" not in row:
                raise ConfigError(f"decode_signals: row {k} lacks {s} or Qf_{s}")
            v, q = row[s], row[f"Qf_{s}"]
            if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool):
                sna, scale = sna_phys[s]
                values[s][k] = np.nan if sna is not None and abs(float(v) - sna) < scale / 2 else float(v)
            else:                       # a choice name (NamedSignalValue or str): only SNA has one
                values[s][k] = np.nan
            qual[s][k] = _qualifier(q)
    return _assemble(values, qual, np.ones(n, dtype=bool), 0)


# ---- running ---------------------------------------------------------------------------------

ALL_VARIANTS = (*tf.VARIANTS, ADAPTIVE)
#: SKFMEC-A calibrated for the car the run's plant plays, where that is not the ECU's car (the demo's
#: daemon serves one car; another plant may run another tyre: sim.car.played_by)
PLANT_CAR = "skfmec-a, plant's car"


def _run(v: str, u: tf.Inputs, dec: DecodedInputs, car=None) -> tf.TireForceRun:
    if car is None:  # the C defaults: the paper's car
        return AdaptiveSkfmec().run(u, dec.mask, dec.ride) if v == ADAPTIVE else tf.estimator(v).run(u, dec.mask)
    if v == ADAPTIVE:
        return AdaptiveSkfmec(tf.SkfConfig.for_car(car), AdaptiveConfig.for_car(car)).run(u, dec.mask, dec.ride)
    return tf.estimator(v, tf.SkfConfig.for_car(car, tf.EKF if v == tf.EKF else tf.SKFMEC)).run(u, dec.mask)


def run_estimators(decoded: DecodedInputs, variants=ALL_VARIANTS, car=None) -> dict[str, tf.TireForceRun]:
    """Each estimator variant (fresh instance, default configuration calibrated for `car`, a
    :class:`~vehest_can.carfile.CarFile`; None: the paper's) over the decoded drive: the paper's three and
    SKFMEC-A (adaptive.py, with the ride heights where the car has them)."""
    u = decoded.for_filter()
    return {v: _run(v, u, decoded, car) for v in variants}


def scenario(name: str, *, mass_delta_kg: float | None = None):
    """A tyre-force scenario by name or path; ``mass_delta_kg`` overrides ``[vehicle] mass_delta_kg``
    (e.g. 0 for the nominal car: the estimator's model is then the true mass)."""
    from ...schema import read_toml
    from .scenario import load_tireforce_scenario, tireforce_scenario_from_dict, tireforce_scenario_path

    if mass_delta_kg is None:
        return load_tireforce_scenario(name)
    path = tireforce_scenario_path(name)
    doc = read_toml(path)
    doc.setdefault("vehicle", {})["mass_delta_kg"] = float(mass_delta_kg)
    doc["name"] = f"{doc.get('name', path.stem)}_mass{mass_delta_kg:+g}kg"
    return tireforce_scenario_from_dict(doc, path)


def simulate(sc, variants=ALL_VARIANTS, progress=None, car=None):
    """Plant + sensor node offline, decode, estimators calibrated for `car` (None: the car the scenario's
    plant plays, :func:`~vehest_can.sim.car.played_by` of the scenario's car or the paper's):
    (truth, DecodedInputs, runs)."""
    from ...carfile import car_of, paper_car
    from ...native import ffi, lib
    from ...sim.car import played_by

    car = car or played_by(car_of(sc) or paper_car(), sc.plant)

    steps = 2 + len(variants)
    truth, frames = sc.run_with_frames(ffi, lib)
    if progress:
        progress(1, steps)
    dec = decode_inputs(frames)
    if progress:
        progress(2, steps)
    u = dec.for_filter()
    runs = {}
    for i, v in enumerate(variants):
        runs[v] = _run(v, u, dec, car)
        if progress:
            progress(3 + i, steps)
    return truth, dec, runs


# ---- metrics ---------------------------------------------------------------------------------

def _rms(a, axis=0):
    a = np.asarray(a, dtype=np.float64)
    return np.sqrt(np.nanmean(a * a, axis=axis))


def _per(names, values) -> dict[str, float]:
    return {k: float(v) for k, v in zip(names, values)}


def _axles(fy: np.ndarray) -> np.ndarray:
    """(n, 2) axle means (Fy1 + Fy2)/2, (Fy3 + Fy4)/2 — the paper's F_yf, F_yr."""
    return np.c_[0.5 * (fy[:, 0] + fy[:, 1]), 0.5 * (fy[:, 2] + fy[:, 3])]


def _true_split(axle: np.ndarray, fz: np.ndarray) -> np.ndarray:
    """Per-tire forces from axle means and the true load share of each tire: F_yi = 2 F_y,axle
    F_zi / (F_z,inner + F_z,outer) — eq. 36-37 with the true loads, normalised so the axle sum is kept."""
    ff = fz[:, :2].sum(axis=1, keepdims=True)
    fr = fz[:, 2:].sum(axis=1, keepdims=True)
    return np.c_[2 * axle[:, :1] * fz[:, :2] / ff, 2 * axle[:, 1:] * fz[:, 2:] / fr]


def _pct_errors(est: np.ndarray, ref: np.ndarray | float, peak: np.ndarray, names) -> dict[str, float]:
    return _per(names, 100.0 * _rms(est - ref) / peak)


def evaluate(truth, runs: dict[str, tf.TireForceRun], settle_s: float = SETTLE_S,
             max_ay_g: float | None = None, true_mass_kg: float | None = None,
             model_mass_kg: float | None = None) -> dict:
    """Per-tire and per-axle RMS errors of each run against the truth, the fixed-vs-double
    difference, the oracle decomposition and a verdict per acceptance line.

    ``truth`` needs ``t`` (n,), ``fy`` and ``fz`` (n, 4) (the plant's record array, or a dict);
    each run's rows are the truth's ticks. RMS is over t >= t[0] + settle_s; percentages are of the
    tire's (axle's) peak |F_y| over the whole run. ``max_ay_g`` keeps only the samples with the
    truth's |a_y| at or below it (needs ``ay``; the paper's relations hold below ~0.5 g), peaks
    then taken over those samples too. ``true_mass_kg`` (the plant's mass) adds the mass estimate's
    acceptance line; ``model_mass_kg`` is the estimators' car's (None: the paper's). Axle estimates are
    the means of the two per-tire estimates, compared with the true axle means (F_yf, F_yr of the paper: average tire force).
    """
    t = np.asarray(truth["t"], dtype=np.float64)
    fy = np.asarray(truth["fy"], dtype=np.float64)
    fz = np.asarray(truth["fz"], dtype=np.float64)
    n = len(t)
    band = np.ones(n, dtype=bool)
    if max_ay_g is not None:
        band = np.abs(np.asarray(truth["ay"], dtype=np.float64)) <= max_ay_g * G
    s = band & (t - t[0] >= settle_s - 1e-9)
    if not s.any():
        raise ConfigError(f"settle_s {settle_s} (max_ay_g {max_ay_g}) leaves no samples of a "
                          f"{t[-1] - t[0]:.3f} s run")
    axle = _axles(fy)
    peak = np.abs(fy[band]).max(axis=0)
    peak_axle = np.abs(axle[band]).max(axis=0)
    if np.any(peak <= 0) or np.any(peak_axle <= 0):
        raise ConfigError("a tire without lateral force: percentages of peak |Fy| are undefined")
    dt = t[1] - t[0] if n > 1 else 0.0
    out: dict = {"settle_s": settle_s, "max_ay_g": max_ay_g, "samples": int(s.sum()), "true_mass_kg": true_mass_kg,
                 "model_mass_kg": tf.SkfConfig.default().m if model_mass_kg is None else model_mass_kg,
                 "duration_s": float(t[-1] - t[0] + dt),
                 "peak_fy_N": _per(WHEELS + AXLES, np.r_[peak, peak_axle]), "variants": {}}
    for name, run in runs.items():
        est = np.asarray(run.fy, dtype=np.float64)
        if est.shape != fy.shape:
            raise ConfigError(f"run {name!r}: fy has shape {est.shape}, the truth {fy.shape}")
        est_axle = _axles(est)
        err, err_axle = est[s] - fy[s], est_axle[s] - axle[s]
        gain = (est_axle[s] * axle[s]).sum(axis=0) / (axle[s] ** 2).sum(axis=0)
        health = np.bincount(np.asarray(run.health, dtype=np.int64), minlength=4)[:4]
        out["variants"][name] = {
            "rms_N": _per(WHEELS + AXLES, np.r_[_rms(err), _rms(err_axle)]),
            "rms_pct": _per(WHEELS + AXLES, 100 * np.r_[_rms(err) / peak, _rms(err_axle) / peak_axle]),
            "mean_error_N": _per(WHEELS + AXLES, np.r_[err.mean(axis=0), err_axle.mean(axis=0)]),
            "axle_scale_pct": _per(AXLES, 100 * (gain - 1)),
            "axle_only_pct": _pct_errors(_true_split(est_axle, fz)[s], fy[s], peak, WHEELS),
            "saturations": int(run.saturations), "resets": int(run.resets),
            "health": _per(("INIT", "OK", "DEGRADED", "FAULT"), health),
        }
        if isinstance(run, AdaptiveRun) and run.mass is not None and run.mass_std is not None:
            mass, std = run.mass, run.mass_std
            ok = np.flatnonzero(std <= AdaptiveConfig().mass_sigma_ok * out["model_mass_kg"])
            out["variants"][name]["mass"] = {"final_kg": float(mass[-1]), "final_std_kg": float(std[-1]),
                                             "converged_s": float(t[ok[0]] - t[0]) if ok.size else None}
            if true_mass_kg:
                out["variants"][name]["mass"]["error_pct"] = float(100 * (mass[-1] / true_mass_kg - 1))
    if tf.SKFMEC in runs and tf.FIXED in runs:
        d = np.asarray(runs[tf.FIXED].fy)[s] - np.asarray(runs[tf.SKFMEC].fy)[s]
        out["fixed_vs_double"] = {"rms_pct": _pct_errors(d, 0.0, peak, WHEELS),
                                  "max_abs_N": _per(WHEELS, np.abs(d).max(axis=0)),
                                  "saturations": int(runs[tf.FIXED].saturations)}
    static = fz[0]
    eq36 = np.c_[axle[:, :1] * fz[:, :2] / static[:2], axle[:, 1:] * fz[:, 2:] / static[2:]]
    out["oracle"] = {
        "split_pct": _pct_errors(_true_split(axle, fz)[s], fy[s], peak, WHEELS),
        "eq36_static_pct": _pct_errors(eq36[s], fy[s], peak, WHEELS),
        "note": "split: true axle means x true load shares 2 Fzi/(Fz_in + Fz_out) (relation 2 alone); "
                "eq36_static: the formula as the estimator uses it, true axle means x Fzi / true static "
                "load (adds the longitudinal load transfer to the axle force); axle_only_pct (per "
                "variant): the estimated axle means x true load shares (the axle estimate alone)",
    }
    out["acceptance"] = acceptance(out)
    return out


def acceptance(m: dict) -> list[dict]:
    """Verdict per acceptance line: 'pass' or 'SHORT', with the figures that decide it."""
    lines = []
    v = m["variants"]
    split = m["oracle"]["split_pct"]
    for name in (tf.FIXED, tf.SKFMEC, ADAPTIVE, PLANT_CAR):
        if name not in v:
            continue
        pct = v[name]["rms_pct"]
        over = [w for w in WHEELS if pct[w] > TARGET_TIRE_PCT]
        if over:
            detail = ("over: " + ", ".join(f"{w} {pct[w]:.2f} %" for w in over)
                      + f"; axles {pct['front']:.2f} / {pct['rear']:.2f} %; axle scale "
                      + " / ".join(f"{v[name]['axle_scale_pct'][a]:+.1f} %" for a in AXLES)
                      + "; split alone (true axle forces, true load shares) "
                      + ", ".join(f"{w} {split[w]:.2f} %" for w in over))
        else:
            detail = f"worst {max(pct[w] for w in WHEELS):.2f} %"
        lines.append({"line": f"per-tire RMS <= {TARGET_TIRE_PCT:g} % of peak |Fy| ({name})",
                      "verdict": "SHORT" if over else "pass", "detail": detail})
    mm, true = v.get(ADAPTIVE, {}).get("mass"), m.get("true_mass_kg")
    # a line where there was a payload to find or an excitation that found one (a run at the
    # model's mass without longitudinal excitation rightly stays unconverged: no target there)
    if mm is not None and true is not None and (mm["converged_s"] is not None or
                                                true != m.get("model_mass_kg", tf.SkfConfig.default().m)):
        conv = f"converged at {mm['converged_s']:.2f} s" if mm["converged_s"] is not None else "not converged"
        ok = abs(100 * (mm["final_kg"] / true - 1)) <= TARGET_MASS_PCT and mm["converged_s"] is not None
        lines.append({"line": f"mass estimate within {TARGET_MASS_PCT:g} % of the truth ({ADAPTIVE})",
                      "verdict": "pass" if ok else "SHORT", "detail": f"{_mass_vs_truth(mm['final_kg'], true)}, {conv}"})
    if "fixed_vs_double" in m:
        fd = m["fixed_vs_double"]
        worst = max(fd["rms_pct"].values())
        ok = worst <= TARGET_FIXED_PCT and fd["saturations"] == 0
        lines.append({"line": f"fixed vs double <= {TARGET_FIXED_PCT:g} % of peak per tire, no saturation",
                      "verdict": "pass" if ok else "SHORT",
                      "detail": f"worst {worst:.4f} %, {fd['saturations']} saturations"})
    if tf.SKFMEC in v and tf.EKF in v:
        d = {w: v[tf.SKFMEC]["rms_pct"][w] - v[tf.EKF]["rms_pct"][w] for w in WHEELS + AXLES}
        better = [w for w in WHEELS if d[w] < 0]
        detail = "SKFMEC - EKF: " + ", ".join(f"{w} {d[w]:+.3f}" for w in WHEELS + AXLES) + " points of peak"
        lines.append({"line": "SKFMEC (double) better than the plain EKF on every tire",
                      "verdict": "pass" if len(better) == len(WHEELS) else "SHORT",
                      "detail": (f"better on {len(better)} of 4 tires; " if better else "better on no tire; ")
                      + detail})
    return lines


def _mass_vs_truth(mass_kg: float, true_kg: float) -> str:
    return f"{mass_kg:.0f} kg, truth {true_kg:.0f} kg ({100 * (mass_kg / true_kg - 1):+.1f} %)"


def relations(truth, config: tf.SkfConfig | None = None, band_g=AY_BAND_G) -> dict:
    """The paper's two relations measured on the truth (Fig. 3-4), within the a_y band.

    Relation 1 (eq. 31-32): zeta1 = F_yf / phi, zeta2 = F_yr / phi (F_yf, F_yr axle means).
    Relation 2 (eq. 33-34): F_yi / F_yf against F_zi / F_zf, F_zf the static load of one tire (the
    truth's first sample: the plant starts in static equilibrium). ``share_ratio`` is
    (F_yi/F_yf - 1) / (F_zi/F_zf - 1) of the outer tires: 1 where relation 2 holds exactly.
    """
    cfg = config or tf.SkfConfig.default(tf.SKFMEC)
    fy, fz = np.asarray(truth["fy"], float), np.asarray(truth["fz"], float)
    phi, ay = np.asarray(truth["phi"], float), np.asarray(truth["ay"], float)
    axle = _axles(fy)
    g = np.abs(ay) / G
    sel = (g >= band_g[0]) & (g <= band_g[1])
    out = {"band_g": list(band_g), "samples": int(sel.sum()),
           "zeta_model_N_per_rad": {"zeta1": cfg.zeta1, "zeta2": cfg.zeta2}}
    if not sel.any():
        return out
    z1, z2 = axle[sel, 0] / phi[sel], axle[sel, 1] / phi[sel]
    for key, z, ref in (("zeta1", z1, cfg.zeta1), ("zeta2", z2, cfg.zeta2)):
        out[key] = {"first": float(z[0]), "last": float(z[-1]), "min": float(z.min()), "max": float(z.max()),
                    "spread_pct": float(100 * (z.max() - z.min()) / np.median(z)),
                    "median_vs_model_pct": float(100 * (np.median(z) / ref - 1))}
    static = fz[0]
    for i, w in enumerate(WHEELS):
        ys = fy[sel, i] / axle[sel, i // 2]
        zs = fz[sel, i] / static[i]
        out[f"share_{w}"] = {"fy_share_range": [float(ys.min()), float(ys.max())],
                             "fz_share_range": [float(zs.min()), float(zs.max())],
                             "share_ratio_median": float(np.median((ys - 1) / (zs - 1)))}
    return out


# ---- table -----------------------------------------------------------------------------------

def plants_table(metrics: list[dict]) -> str:
    """The runs on both plants side by side: per scenario and plant, each variant's worst tyre and
    worst axle (RMS, % of peak |Fy|) and SKFMEC-A's mass against the truth."""
    names = [v for v in (tf.SKFMEC, tf.FIXED, ADAPTIVE, PLANT_CAR) if any(v in m["variants"] for m in metrics)]
    label = {PLANT_CAR: "plant's car"}
    head = (f"{'scenario':<28}{'plant':<15}" + "".join(f"{label.get(v, v) + ' tyre':>20}{'axle':>7}" for v in names)
            + f"{'mass':>9}")
    lines = ["== tyre force on both plants: worst tyre / worst axle RMS, % of peak |Fy|; SKFMEC-A mass error"
             + (f" ('plant's car': {PLANT_CAR}, where the plant runs another tyre than the ECU's car)"
                if PLANT_CAR in names else ""), head, "-" * len(head)]
    for m in sorted(metrics, key=lambda m: (m["scenario"].split("@")[0], m.get("plant", ""))):
        cells = ""
        for v in names:
            pct = m["variants"].get(v, {}).get("rms_pct")
            cells += (f"{max(pct[w] for w in WHEELS):>19.2f}{'!' if max(pct[w] for w in WHEELS) > TARGET_TIRE_PCT else ' '}"
                      f"{max(pct[a] for a in AXLES):>7.2f}") if pct else f"{'-':>20}{'-':>7}"
        mm, true = m["variants"].get(ADAPTIVE, {}).get("mass"), m.get("true_mass_kg")
        mass = f"{100 * (mm['final_kg'] / true - 1):>+8.1f}%" if mm and true else f"{'-':>9}"
        lines.append(f"{m['scenario'].split('@')[0]:<28}{m.get('plant', ''):<15}{cells}{mass}")
    lines.append(f"(!: over the {TARGET_TIRE_PCT:g} % target)")
    return "\n".join(lines)


def table(metrics: dict, name: str | None = None) -> str:
    """Terminal table: per tire and axle, each variant, RMS error in % of peak |Fy|; '!' marks a
    tire over the 10 % target; then the decomposition and the acceptance lines."""
    name = name or metrics.get("scenario", "")
    cols = WHEELS + AXLES
    head = f"{'':<22}" + "".join(f"{c:>9}" for c in cols) + f"{'sat':>6}{'resets':>8}"
    band = f", |a_y| <= {metrics['max_ay_g']:g} g" if metrics.get("max_ay_g") is not None else ""
    lines = [f"== {name}: RMS error after {metrics['settle_s']:g} s{band}, % of peak |Fy| "
             f"({metrics['samples']} samples)", head, "-" * len(head)]
    lines.append(f"{'peak |Fy| [N]':<22}" + "".join(f"{metrics['peak_fy_N'][c]:>9.0f}" for c in cols))
    for v, vm in metrics["variants"].items():
        cells = ""
        for c in cols:
            mark = "!" if c in WHEELS and vm["rms_pct"][c] > TARGET_TIRE_PCT else " "
            cells += f"{vm['rms_pct'][c]:>8.2f}{mark}"
        lines.append(f"{v:<22}{cells}{vm['saturations']:>6d}{vm['resets']:>8d}")
    for v, vm in metrics["variants"].items():
        if v == tf.SKFMEC:
            lines.append(f"{'  axle scale (SKFMEC)':<22}" + " " * 36
                         + "".join(f"{vm['axle_scale_pct'][a]:>+8.1f}%" for a in AXLES))
            lines.append(f"{'  axle only (SKFMEC)':<22}" + "".join(f"{vm['axle_only_pct'][w]:>9.2f}" for w in WHEELS))
    for v, vm in metrics["variants"].items():
        if "mass" in vm:
            mm = vm["mass"]
            true = metrics.get("true_mass_kg") or tf.SkfConfig.default().m + metrics.get("mass_delta_kg", 0.0)
            conv = f"converged at {mm['converged_s']:.2f} s" if mm["converged_s"] is not None else "not converged (DEGRADED)"
            lines.append(f"{'  mass (' + v + ')':<22} {_mass_vs_truth(mm['final_kg'], true)}, "
                         f"std {mm['final_std_kg']:.0f} kg, {conv}")
    o = metrics["oracle"]
    lines.append(f"{'oracle: split only':<22}" + "".join(f"{o['split_pct'][w]:>9.2f}" for w in WHEELS))
    lines.append(f"{'oracle: eq.36, static':<22}" + "".join(f"{o['eq36_static_pct'][w]:>9.2f}" for w in WHEELS))
    if "fixed_vs_double" in metrics:
        fd = metrics["fixed_vs_double"]
        lines.append(f"{'fixed - double':<22}" + "".join(f"{fd['rms_pct'][w]:>9.4f}" for w in WHEELS)
                     + " " * 18 + f"{fd['saturations']:>6d}")
    lines.append(f"(!: a tyre over the {TARGET_TIRE_PCT:g} % target)")
    lines.append("acceptance:")
    for a in metrics["acceptance"]:
        lines.append(f"  [{verdict_word(a['verdict'])}] {a['line']}: {a['detail']}")
    return "\n".join(lines)


# ---- plots -----------------------------------------------------------------------------------

_STYLE: dict[str, dict[str, Any]] = {tf.SKFMEC: dict(color="tab:blue", lw=1.0, label="SKFMEC (double)"),
          tf.FIXED: dict(color="tab:cyan", lw=1.0, ls="--", label="SKFMEC (fixed point, ECU)"),
          tf.EKF: dict(color="tab:orange", lw=1.0, label="plain EKF"),
          ADAPTIVE: dict(color="tab:green", lw=1.0, label="SKFMEC-A (adaptive mass, load-sensitive split)")}


def _ylim_after(ax, t, curves, settle_s):
    """y limits from the samples after the settling time (the filters' first-step transient would
    otherwise set the scale); the settling window is shaded."""
    sel = t - t[0] >= settle_s
    vals = np.concatenate([np.asarray(c)[sel].ravel() for c in curves])
    vals = vals[np.isfinite(vals)]
    if vals.size:
        lo, hi = vals.min(), vals.max()
        pad = 0.08 * max(hi - lo, 1e-9)
        ax.set_ylim(lo - pad, hi + pad)
    ax.axvspan(t[0], t[0] + settle_s, color="0.92", lw=0)


def plots(kind: str, truth, runs: dict[str, tf.TireForceRun] | None, out_dir: Path, *, title: str = "",
          config: tf.SkfConfig | None = None, settle_s: float = SETTLE_S,
          true_mass_kg: float | None = None) -> list[Path]:
    """PNG figures into ``out_dir``. ``kind`` "relations": Fig. 3 (zeta1, zeta2 from the truth over
    time with the model's constants) and Fig. 4 (F_yi/F_yf against F_zi/F_zf, identity line);
    "forces": Fig. 5 and 6 (inner FL and outer FR front lateral force: truth and each run) and the
    per-tire error of every run (y scale from t >= settle_s; the settling window shaded), and
    SKFMEC-A's mass estimate over time (``mass.png``, with ``true_mass_kg`` when given) and the friction
    its split assumed per side with the road's estimate, against the plant's (``friction.png``)."""
    plt = pyplot()
    figs = Figures(out_dir)
    t = np.asarray(truth["t"], float)
    fy, fz = np.asarray(truth["fy"], float), np.asarray(truth["fz"], float)
    axle = _axles(fy)
    prefix = f"{title}: " if title else ""

    save = figs.save

    def save_over_time(fig, ax, ylabel: str, what: str, name: str) -> None:
        """A one-panel figure over time finished alike: axis labels, title, grid, legend; written."""
        ax.set_xlabel("time [s]")
        ax.set_ylabel(ylabel)
        ax.set_title(prefix + what)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        save(fig, name)

    if kind == "relations":
        cfg = config or tf.SkfConfig.default(tf.SKFMEC)
        g = np.abs(np.asarray(truth["ay"], float)) / G
        phi = np.asarray(truth["phi"], float)
        ok = g >= AY_BAND_G[0]
        fig, ax = plt.subplots(figsize=(10, 4.5))
        for j, (lab, ref, col) in enumerate((("ζ1 = F_yf / φ", cfg.zeta1, "tab:blue"),
                                             ("ζ2 = F_yr / φ", cfg.zeta2, "tab:red"))):
            z = np.where(ok, axle[:, j] / np.where(ok, phi, 1.0), np.nan)
            ax.plot(t, z / 1e3, color=col, lw=1.2, label=f"{lab} (plant truth, a_y ≥ {AY_BAND_G[0]:g} g)")
            ax.axhline(ref / 1e3, color=col, ls=":", lw=1, label=f"model constant {ref / 1e3:.1f} kN/rad")
        over = np.nonzero(g > AY_BAND_G[1])[0]
        if len(over):
            ax.axvspan(t[over[0]], t[-1], color="0.9", label=f"a_y > {AY_BAND_G[1]:g} g")
        save_over_time(fig, ax, "ζ [kN/rad]", "Fig. 3: ζ1, ζ2 (relation 1, eq. 31-32)", "fig3_zeta.png")

        fig, axes = plt.subplots(1, 2, figsize=(11, 5))
        static = fz[0]
        for ax, pair, axname in ((axes[0], (0, 1), "front"), (axes[1], (2, 3), "rear")):
            lo, hi = 1.0, 1.0
            for i, col in zip(pair, ("tab:blue", "tab:red")):
                ys = np.where(ok, fy[:, i] / np.where(ok, axle[:, i // 2], 1.0), np.nan)
                zs = fz[:, i] / static[i]
                inner = "inner" if i % 2 == 0 else "outer"
                ax.scatter(zs[ok], ys[ok], s=2, c=col, label=f"F_y{i + 1}/F_y{axname[0]} ({WHEELS[i]}, {inner})")
                sel = ok & (g > AY_BAND_G[1])
                if sel.any():
                    ax.scatter(zs[sel], ys[sel], s=2, c="0.6")
                lo, hi = min(lo, np.nanmin(zs[ok]), np.nanmin(ys[ok])), max(hi, np.nanmax(zs[ok]), np.nanmax(ys[ok]))
            ax.plot([lo, hi], [lo, hi], "k--", lw=1, label="relation 2: F_yi/F_y,axle = F_zi/F_z,static")
            ax.set_xlabel(f"F_zi / F_z{axname[0]} (static load of one tire)")
            ax.set_ylabel(f"F_yi / F_y{axname[0]} (axle mean)")
            ax.set_title(f"{axname} axle" + (" (Fig. 4: tire 2)" if axname == "front" else ""))
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7, loc="upper left")
        fig.suptitle(f"{prefix}relation 2 (eq. 33-34), a_y ≥ {AY_BAND_G[0]:g} g (grey: > {AY_BAND_G[1]:g} g)")
        save(fig, "fig4_share.png")
        return figs.paths

    if kind != "forces":
        raise ConfigError(f"plots: kind must be 'relations' or 'forces', not {kind!r}")
    runs = runs or {}
    for i, (fig_no, what) in enumerate(((5, "inner"), (6, "outer"))):
        fig, ax = plt.subplots(figsize=(10, 4.5))
        ax.plot(t, fy[:, i], "k-", lw=1.6, label="truth (14-DOF plant)")
        for v in (tf.FIXED, tf.SKFMEC, tf.EKF, ADAPTIVE):
            if v in runs:
                ax.plot(t, runs[v].fy[:, i], **_STYLE[v])
        _ylim_after(ax, t, [fy[:, i]] + [runs[v].fy[:, i] for v in runs], settle_s)
        save_over_time(fig, ax, f"F_y{i + 1} [N]", f"Fig. {fig_no}: {what}-front lateral force ({WHEELS[i]})",
                       f"fig{fig_no}_{what}_front.png")
    fig, axes = plt.subplots(4, 1, figsize=(10, 10), sharex=True)
    peak = np.abs(fy).max(axis=0)
    for i, ax in enumerate(axes):
        errs = [100 * (runs[v].fy[:, i] - fy[:, i]) / peak[i] for v in runs]
        for v in (tf.FIXED, tf.SKFMEC, tf.EKF, ADAPTIVE):
            if v in runs:
                ax.plot(t, 100 * (runs[v].fy[:, i] - fy[:, i]) / peak[i], **_STYLE[v])
        ax.axhline(0, color="k", lw=0.6)
        if errs:
            _ylim_after(ax, t, errs, settle_s)
        ax.set_ylabel(f"{WHEELS[i]} [% of {peak[i]:.0f} N]")
        ax.grid(alpha=0.3)
    axes[0].set_title(f"{prefix}estimate − truth per tire, % of the tire's peak |F_y|")
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel("time [s]")
    save(fig, "error_per_tire.png")
    run = runs.get(ADAPTIVE)
    if isinstance(run, AdaptiveRun) and run.mass is not None and run.mass_std is not None:
        fig, ax = plt.subplots(figsize=(10, 4))
        ax.plot(t, run.mass, color="tab:green", lw=1.2, label="m̂ (SKFMEC-A: RLS on the balance and the ride heights)")
        ax.fill_between(t, run.mass - 2 * run.mass_std, run.mass + 2 * run.mass_std, color="tab:green", alpha=0.15,
                        label="± 2 std")
        if true_mass_kg is not None:
            ax.axhline(true_mass_kg, color="k", lw=1.2, label=f"truth {true_mass_kg:.0f} kg")
        ax.axhline(tf.SkfConfig.default().m, color="0.5", ls=":", lw=1, label="model mass (the paper's car)")
        save_over_time(fig, ax, "mass [kg]", "estimated mass", "mass.png")
    if isinstance(run, AdaptiveRun) and run.mu is not None and "mu" in (truth.dtype.names or ()):
        mu = np.asarray(truth["mu"], float)
        fig, ax = plt.subplots(figsize=(10, 4))
        for i, (side, col) in enumerate((("left", "tab:blue"), ("right", "tab:red"))):
            ax.plot(t, mu[:, i], color=col, lw=2.2, alpha=0.35, label=f"truth, {side} side")
            ax.plot(t, run.mu[:, i], color=col, lw=1.2, label=f"SKFMEC-A, {side} tyres' μ (the split's)")
        if run.road_mu is not None:
            ax.plot(t, run.road_mu, color="tab:green", ls=":", lw=1.4, label="road μ̂ (kinematic coupling, item 9)")
        ax.set_ylim(0.0, max(1.2, float(np.nanmax(mu)) + 0.05))
        save_over_time(fig, ax, "friction μ", "friction: the truth and what the split assumed", "friction.png")
    return figs.paths


# ---- command line ----------------------------------------------------------------------------

def true_mass(sc) -> float:
    """The plant's mass in a scenario: its car's (the paper's unless it names one) plus the payload."""
    from ...carfile import car_of

    car = car_of(sc)
    return (tf.SkfConfig.default().m if car is None else car.total_mass_kg) + sc.mass_delta_kg


def report(sc, out_dir: Path | None = None, progress=None, max_ay_g: float | None = None) -> dict:
    """One scenario: simulate, evaluate, relations, plots (when out_dir). Returns the metrics."""
    truth, dec, runs = simulate(sc, progress=progress)
    m = evaluate(truth, runs, max_ay_g=max_ay_g, true_mass_kg=true_mass(sc))
    m = {"scenario": sc.name, "description": sc.description, "mass_delta_kg": sc.mass_delta_kg,
         "e2e_rejected": dec.e2e_rejected, "invalid_samples": dec.invalid, **m,
         "relations": relations(truth)}
    if out_dir is not None:
        d = Path(out_dir) / sc.name
        files = plots("relations", truth, None, d, title=sc.name) + plots("forces", truth, runs, d, title=sc.name,
                                                                                 true_mass_kg=true_mass(sc))
        m["plots"] = [str(p) for p in files]
    return m


def main(argv: list[str], prog: str) -> int:
    from ...progress import Progress
    from .scenario import list_tireforce_scenarios

    ap = argparse.ArgumentParser(prog=prog, description=__doc__.split("\n")[0])
    ap.add_argument("scenarios", nargs="*", help="tyre-force scenario files or shipped names (default: all shipped)")
    ap.add_argument("-o", "--out", type=Path, default=Path("out/tfreport"), help="output directory")
    ap.add_argument("--mass-delta", type=float, default=None, metavar="KG",
                    help="override [vehicle] mass_delta_kg (0: the nominal car, the estimator's mass)")
    ap.add_argument("--max-ay-g", type=float, default=None, metavar="G",
                    help="evaluate only the samples with the truth's |a_y| at or below G "
                         "(the paper: the relations hold below 0.5 g)")
    args = ap.parse_args(argv)
    all_metrics = []
    try:
        for name in args.scenarios or list_tireforce_scenarios():
            sc = scenario(name, mass_delta_kg=args.mass_delta)
            bar = Progress(sc.name)
            m = report(sc, args.out, progress=bar, max_ay_g=args.max_ay_g)
            bar.done(f"{len(m.get('plots', []))} plots")
            all_metrics.append(m)
            print(table(m))
            print()
    except ScenarioError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    write_metrics(all_metrics, args.out / "metrics.json")
    print(f"metrics: {args.out / 'metrics.json'}; plots in {args.out}/<scenario>/")
    return 0

