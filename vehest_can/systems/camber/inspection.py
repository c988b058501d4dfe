"""Camber inspection on the bus (seed 002): captures of the devices' CIS_Accel frames, per-wheel
calibration from them, the ECU's VEHEST_Camber results, and the paper's Fig. 5.

The numerics are the firmware's (``vehest_can.systems.camber.api`` over ``c_core/camber/vh_camber.c``); this
module only moves frames: every CIS_Accel frame is E2E-checked (the firmware's own check) before
its samples are used, and refused frames are counted, never used.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import numpy as np

from ...bus.frames import E2E_USABLE, authentic_data, database, e2e_check, e2e_config
from ...errors import ConfigError
from ...native import ffi, lib
from ...plotting import Figures, pyplot
from .api import WHEELS, Calibration, CaptureError, calibrate

CIS = database("pt").get_message_by_name("CIS_Accel")
CAMBER = database("pt").get_message_by_name("VEHEST_Camber")
REASONS = {0: "OK", 1: "MOVING", 2: "NOT_STATIONARY", 3: "MAGNITUDE", 4: "TOO_FEW_SAMPLES",
           5: "NOT_CALIBRATED", 6: "SATURATED", 7: "NO_RESULT_YET"}


@dataclass
class Capture:
    """Raw counts per wheel from CIS_Accel frames, and what was refused on the way."""

    samples: dict[str, list] = field(default_factory=lambda: {w: [] for w in WHEELS})
    lsb_g: float | None = None
    frames: int = 0
    refused: int = 0

    def add(self, msg: can.Message, e2e) -> None:
        if msg.arbitration_id != CIS.frame_id or msg.is_extended_id:
            return
        data = bytes(msg.data)
        if len(data) != CIS.length or e2e_check(e2e_config(CIS), e2e, data) not in E2E_USABLE:
            self.refused += 1
            return
        d: Any = CIS.decode(data, decode_choices=False)
        self.frames += 1
        self.lsb_g = d["CIS_LsbMicroG"] * 1e-6
        for i, w in enumerate(WHEELS):
            if int(d["CIS_Present"]) & (1 << i):
                self.samples[w].append((d[f"CIS_AccX_{w}"], d[f"CIS_AccY_{w}"], d[f"CIS_AccZ_{w}"]))

    def array(self, wheel: str) -> np.ndarray:
        return np.asarray(self.samples[wheel], dtype=np.int16).reshape(-1, 3)


def capture_messages(messages) -> Capture:
    cap = Capture()
    e2e = ffi.new("vh_e2e_rx_t *")
    lib.vh_e2e_rx_init(e2e)
    for m in messages:
        cap.add(m, e2e)
    return cap


def capture_bus(bus: can.BusABC, samples: int, timeout: float) -> Capture:
    """Receive CIS_Accel frames until every present device gave `samples` samples."""
    cap = Capture()
    e2e = ffi.new("vh_e2e_rx_t *")
    lib.vh_e2e_rx_init(e2e)
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        msg = bus.recv(timeout=0.1)
        if msg is not None:
            cap.add(msg, e2e)
            present = [w for w in WHEELS if cap.samples[w]]
            if present and all(len(cap.samples[w]) >= samples for w in present):
                return cap
    raise ConfigError(f"capture: {min((len(v) for v in cap.samples.values()), default=0)} of {samples} samples "
                      f"within {timeout:.0f} s ({cap.frames} CIS_Accel frames, {cap.refused} refused): "
                      "are the inspection devices on this bus?")


def calibrate_wheels(x_down: Capture, z_down: Capture, wheels=None) -> dict[str, Calibration]:
    """eq. 7-19 per wheel; a bad capture raises CaptureError naming the wheel."""
    wheels = wheels or [w for w in WHEELS if x_down.samples[w] or z_down.samples[w]]
    if not wheels:
        raise CaptureError("no CIS_Accel samples in the captures: no inspection device was sampling")
    if x_down.lsb_g is None or z_down.lsb_g is None or not math.isclose(x_down.lsb_g, z_down.lsb_g):
        raise CaptureError("the two captures disagree on the accelerometer resolution (CIS_LsbMicroG)")
    out = {}
    for w in wheels:
        try:
            out[w] = calibrate(x_down.array(w), z_down.array(w), lsb_g=x_down.lsb_g)
        except CaptureError as exc:
            raise CaptureError(f"wheel {w}: {exc}") from None
    return out


def ecu_results(messages) -> dict[str, dict] | None:
    """The last VEHEST_Camber frame with a good E2E check, per wheel; None if there was none."""
    e2e = ffi.new("vh_e2e_rx_t *")
    lib.vh_e2e_rx_init(e2e)
    last: Any = None
    for m in messages:
        if m.arbitration_id != CAMBER.frame_id or m.is_extended_id or len(m.data) != CAMBER.length:
            continue
        data = authentic_data(CAMBER.frame_id, bytes(m.data))  # its SecOC tail, if on, is not the CRC's
        if e2e_check(e2e_config(CAMBER), e2e, data) in E2E_USABLE:
            last = CAMBER.decode(bytes(m.data), decode_choices=False)
    if last is None:
        return None
    return {w: {"camber_deg": last[f"Camber_{w}"], "misalign_deg": last[f"Misalign_{w}"],
                "bound_deg": last[f"CamberBound_{w}"], "reason": REASONS[int(last[f"CamberReason_{w}"])]}
            for w in WHEELS}


def results_table(results: dict[str, dict], truth: dict[str, tuple[float, float]] | None = None) -> str:
    head = f"{'wheel':<6}{'camber':>10}{'bound':>9}{'misalign':>10}  status"
    if truth:
        head += f"{'true camber':>14}{'error':>9}"
    lines = [head]
    for w, r in results.items():
        ok = r["reason"] == "OK"
        line = (f"{w:<6}{r['camber_deg']:>9.3f}°{r['bound_deg']:>8.3f}°{r['misalign_deg']:>9.2f}°  {r['reason']:<16}"
                if ok else f"{w:<6}{'-':>10}{'-':>9}{'-':>10}  {r['reason']:<16}")
        if truth and w in truth and ok:
            err = r["camber_deg"] - truth[w][0]
            line += f"{truth[w][0]:>10.3f}°{err:>+9.3f}°{'  within bound' if abs(err) <= r['bound_deg'] else '  OUTSIDE bound'}"
        lines.append(line)
    return "\n".join(lines)


def min_worst_case_deg(lsb_mg: float = 4.0) -> float:
    """The paper's headline: worst-case camber error at theta = 0 (eq. 22), degrees."""
    from .api import worst_case_error

    return math.degrees(worst_case_error(0.0, 0.0, lsb_mg * 1e-3))


def bound_plot(path: Path, lsb_mg: float = 4.0) -> Path:
    """Fig. 5: worst-case camber error (eq. 22) over camber and misalignment for a resolution."""
    plt = pyplot()

    from .api import worst_case_error

    theta = np.radians(np.linspace(-10, 10, 81))
    psi = np.radians(np.linspace(-45, 45, 91))
    err = np.array([[math.degrees(worst_case_error(t, p, lsb_mg * 1e-3)) for t in theta] for p in psi])
    fig, ax = plt.subplots(figsize=(7, 5))
    cs = ax.contourf(np.degrees(theta), np.degrees(psi), err, levels=20, cmap="viridis")
    fig.colorbar(cs, label="worst-case camber error [deg]")
    ax.set_xlabel("camber θ [deg]")
    ax.set_ylabel("misalignment ψ [deg]")
    ax.set_title(f"eq. 22 worst-case camber error, {lsb_mg:g} mg per axis "
                 f"(min {min_worst_case_deg(lsb_mg):.4f}° at θ = 0)")
    return Figures(path.parent).save(fig, path.name)
