"""Camber angle inspection (seed 002): Python layer over the C core ``vh_camber``.

* :func:`calibrate` turns two calibration captures (raw int16 counts, device x axis down and
  device z axis down) into a :class:`Calibration`, or raises :class:`CaptureError` saying why.
* :meth:`Calibration.save` / :meth:`Calibration.load` keep per-wheel calibrations in one
  versioned JSON file (see docs/camber.md); loading validates every field.
* :func:`measure` runs the firmware's inspection over a window of raw counts and returns a
  :class:`Result` (camber, misalignment, eq. 22 bound, and a :class:`Reason`).
* :class:`CamberNode` drives the simulated wheel-mounted device (``firmware_sim``).

Angles are in radians, accelerations in g; raw samples are ``(N, 3)`` integer arrays.
"""
from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import ConfigError
from ...native import c_enum, check, config_class, ffi, lib
from ...sim import WHEELS

FORMAT = "vehest-can/camber-calibration"
VERSION = 1
N_MAX = int(lib.VH_CAMBER_N_MAX)
DEFAULT_LSB_G = 0.004  # 4 mg, the paper's resolution
AXIS_NORM_TOL = 1e-3  # a stored axis must be a unit vector to this (the C check)
Y_AXIS_TOL = 1e-6  # a stored y_axis must equal z x x to this


class CaptureError(ConfigError):
    """A calibration capture is unusable; the message says which capture and why."""


Reason: Any = c_enum("vh_camber_reason_t", "Reason", "VH_CAMBER_",
                     "Why the inspection did or did not publish (vh_camber_reason_t).")
CalStatus: Any = c_enum("vh_camber_cal_status_t", "CalStatus", "VH_CAMBER_CAL_",
                        "Outcome of the firmware's calibration (vh_camber_cal_status_t).")


_C_LIMITS: Any = config_class("vh_camber_cal_limits_t", "CalibrationLimits",
                              defaults=lib.vh_camber_cal_limits_default, frozen=True)
_C_MEASURE: Any = config_class("vh_camber_config_t", "MeasureConfig", defaults=lib.vh_camber_config_default, frozen=True)


class CalibrationLimits(_C_LIMITS):
    """Acceptance limits for calibration captures, field for field ``vh_camber_cal_limits_t`` (derived
    from the C struct: :func:`vehest_can.native.config_class`; defaults: the firmware's):
    ``min_samples`` per capture, ``std_max_g`` sqrt(var_x + var_y + var_z) of one capture,
    ``mag_tol_g`` | |mean| - 1 g |, ``ortho_tol`` |x . z|."""

    def _to_c(self):
        if not (isinstance(self.min_samples, int) and 2 <= self.min_samples <= N_MAX):
            raise ConfigError(f"min_samples must be an integer in 2..{N_MAX}, got {self.min_samples!r}")
        _check_positive(self, ("std_max_g", "mag_tol_g", "ortho_tol"))
        return self.to_c()


class MeasureConfig(_C_MEASURE):
    """Inspection acceptance, field for field ``vh_camber_config_t`` (derived from the C struct;
    defaults: the firmware's): ``window`` samples per result in measure_windows(), ``min_samples``,
    ``mag_tol_g`` | |mean a| - 1 g |, ``std_max_g`` sqrt(var_x + var_y + var_z) over the window."""


def _check_positive(config, names) -> None:
    for name in names:
        v = getattr(config, name)
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ConfigError(f"{name} must be a finite number > 0, got {v!r}")


def _check_lsb(lsb_g, where: str) -> tuple[float, float, float]:
    if isinstance(lsb_g, (int, float)) and not isinstance(lsb_g, bool):
        lsb_g = (lsb_g,) * 3
    try:
        vals = tuple(float(v) for v in lsb_g)
    except (TypeError, ValueError):
        raise ConfigError(f"{where}: lsb_g must be a number or 3 numbers (g per count), got {lsb_g!r}") from None
    if len(vals) != 3 or not all(math.isfinite(v) and 0 < v < 1 for v in vals):
        raise ConfigError(f"{where}: lsb_g must be 3 finite numbers in (0, 1) g per count, got {lsb_g!r}")
    return vals


def _as_counts(samples, what: str, error=ConfigError, max_n: int | None = N_MAX) -> np.ndarray:
    """(N, 3) raw counts as a C-contiguous int16 array, or a clear error."""
    arr = np.asarray(samples)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise error(f"{what}: expected raw samples of shape (N, 3), got shape {arr.shape}")
    if arr.dtype == bool or not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
        raise error(f"{what}: expected integer counts, got dtype {arr.dtype}")
    if arr.size and np.issubdtype(arr.dtype, np.floating):
        if not np.all(np.isfinite(arr)):
            raise error(f"{what}: samples contain NaN or infinity")
        if not np.all(arr == np.round(arr)):
            raise error(f"{what}: samples must be raw integer counts, not scaled values")
    if arr.size and (arr.min() < -32768 or arr.max() > 32767):
        raise error(f"{what}: counts outside the int16 range -32768..32767")
    if max_n is not None and len(arr) > max_n:
        raise error(f"{what}: {len(arr)} samples; at most {max_n} fit one window/capture")
    return np.ascontiguousarray(arr, dtype=np.int16)


def _vec3(v, where: str) -> tuple[float, float, float]:
    if not isinstance(v, (list, tuple)) or len(v) != 3:
        raise ConfigError(f"{where}: expected a list of 3 numbers, got {v!r}")
    if not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v):
        raise ConfigError(f"{where}: expected 3 finite numbers, got {v!r}")
    return (float(v[0]), float(v[1]), float(v[2]))


def _check_axes(x, z, where: str) -> None:
    """Stored axes must be unit vectors and square to the firmware's tolerance."""
    for name, v in (("x_axis", x), ("z_axis", z)):
        n = float(np.linalg.norm(v))
        if abs(n - 1.0) > AXIS_NORM_TOL:
            raise ConfigError(f"{where}: {name} must be a unit vector, its norm is {n:.6f}")
    d = float(np.dot(x, z))
    tol = CalibrationLimits().ortho_tol
    if abs(d) > tol:
        raise ConfigError(f"{where}: x_axis and z_axis are not orthogonal (x.z = {d:+.5f}, limit {tol:.5f})")


_POSE_NAME = ("x-down", "z-down", "x-down/z-down")


def _capture_message(rep, st: CalStatus, lim: CalibrationLimits, n_sat: tuple[int, int]) -> str:
    pose = int(rep.pose)
    name = _POSE_NAME[pose]
    if st == CalStatus.TOO_FEW_SAMPLES:
        return f"{name} capture has {rep.n[pose]} samples; at least {max(lim.min_samples, 2)} are needed"
    if st == CalStatus.SATURATED:
        return (f"{name} capture: {n_sat[pose]} samples at the int16 limits (sensor saturated); "
                "check the range setting")
    if st == CalStatus.MOVING:
        return (f"{name} capture spread {rep.std_g[pose]:.4f} g exceeds {lim.std_max_g:.4f} g: "
                "the device moved during the capture; hold it still and capture again")
    if st == CalStatus.MAGNITUDE:
        mag = float(rep.mag_g[pose])
        return (f"{name} capture mean magnitude {mag:.4f} g is {abs(mag - 1):.4f} g from 1 g (limit "
                f"{lim.mag_tol_g:.4f} g): wrong lsb_g, a faulty sensor, or the device was accelerating")
    if st == CalStatus.NOT_ORTHOGONAL:
        d = float(rep.x_dot_z)
        off = math.degrees(math.asin(min(1.0, abs(d))))
        return (f"x and z axes not orthogonal: x.z = {d:+.5f} ({off:.2f} deg off square, limit "
                f"{math.degrees(math.asin(min(1.0, lim.ortho_tol))):.2f} deg); were the two poses "
                "captured on a square fixture, and not the same pose twice?")
    return "captures unusable: different resolutions, non-finite or singular data"


@dataclass(frozen=True)
class Calibration:
    """Chip-in-device calibration of one inspection device (eq. 17-19).

    ``x_axis``/``z_axis`` are the device's x and z axes as seen by the chip (unit vectors in A);
    y = z x x, M = [x y z] (columns), a_S = M^-1 a_A. ``lsb_g`` is the chip resolution (g per
    count). ``capture`` holds what the calibration saw (sample counts, spreads, x.z).
    """

    x_axis: tuple[float, float, float]
    z_axis: tuple[float, float, float]
    lsb_g: tuple[float, float, float] = (DEFAULT_LSB_G,) * 3
    capture: Mapping[str, Any] = field(default_factory=dict, compare=False)
    created: str | None = field(default=None, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "x_axis", _vec3(list(self.x_axis), "calibration x_axis"))
        object.__setattr__(self, "z_axis", _vec3(list(self.z_axis), "calibration z_axis"))
        object.__setattr__(self, "lsb_g", _check_lsb(self.lsb_g, "calibration"))
        _check_axes(self.x_axis, self.z_axis, "calibration")

    @classmethod
    def identity(cls, lsb_g=DEFAULT_LSB_G) -> Calibration:
        """No calibration: assumes the chip is perfectly square in the device (M = I)."""
        return cls((1.0, 0.0, 0.0), (0.0, 0.0, 1.0), lsb_g, capture={"identity": True})

    def _to_c(self):
        cal = ffi.new("vh_camber_cal_t *")
        st = lib.vh_camber_cal_from_axes(cal, self.x_axis, self.z_axis, self.lsb_g, CalibrationLimits().ortho_tol)
        if st != lib.VH_OK:
            raise ConfigError("calibration: the firmware rejected these axes (not unit, not orthogonal or singular)")
        return cal

    @property
    def y_axis(self) -> tuple[float, float, float]:
        c = self._to_c()  # keep the struct alive while reading it
        return tuple(float(v) for v in c.y_axis)  # type: ignore[return-value]

    @property
    def m(self) -> np.ndarray:
        """eq. 19 M (float32 values of the firmware), a_A = M a_S."""
        c = self._to_c()
        return np.array(list(c.m), dtype=float).reshape(3, 3)

    @property
    def m_inv(self) -> np.ndarray:
        """M^-1 as the firmware computed it, a_S = M^-1 a_A."""
        c = self._to_c()
        return np.array(list(c.m_inv), dtype=float).reshape(3, 3)

    @property
    def da_s_g(self) -> np.ndarray:
        """The chip resolution carried to the S axes, |M^-1| lsb: the da of eq. 22."""
        c = self._to_c()
        return np.array(list(c.da_s_g), dtype=float)

    def apply(self, samples) -> np.ndarray:
        """a_S in g for raw counts (N, 3), eq. 19 in the firmware's float32."""
        raw = _as_counts(samples, "samples")
        cal = self._to_c()
        out = np.empty((len(raw), 3))
        cnt = ffi.new("float[3]")
        a_s = ffi.new("float[3]")
        for i, row in enumerate(raw):
            cnt[0], cnt[1], cnt[2] = (float(v) for v in row)
            lib.vh_camber_cal_apply(cal, cnt, a_s)
            out[i] = list(a_s)
        return out

    # ---- file ------------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {
            "x_axis": list(self.x_axis),
            "y_axis": list(self.y_axis),
            "z_axis": list(self.z_axis),
            "lsb_g": list(self.lsb_g),
        }
        if self.capture:
            d["capture"] = dict(self.capture)
        if self.created:
            d["created"] = self.created
        return d

    @classmethod
    def from_dict(cls, d: Any, where: str = "calibration") -> Calibration:
        if not isinstance(d, dict):
            raise ConfigError(f"{where}: expected an object, got {type(d).__name__}")
        allowed = {"x_axis", "y_axis", "z_axis", "lsb_g", "capture", "created"}
        unknown = sorted(set(d) - allowed)
        if unknown:
            raise ConfigError(f"{where}: unknown key(s) {', '.join(unknown)}; allowed: {', '.join(sorted(allowed))}")
        for key in ("x_axis", "z_axis", "lsb_g"):
            if key not in d:
                raise ConfigError(f"{where}: missing key {key!r}")
        x = _vec3(d["x_axis"], f"{where}.x_axis")
        z = _vec3(d["z_axis"], f"{where}.z_axis")
        lsb = _check_lsb(_vec3(d["lsb_g"], f"{where}.lsb_g"), f"{where}")
        capture = d.get("capture", {})
        if not isinstance(capture, dict):
            raise ConfigError(f"{where}.capture: expected an object")
        created = d.get("created")
        if created is not None and not isinstance(created, str):
            raise ConfigError(f"{where}.created: expected a string")
        _check_axes(x, z, where)
        cal = cls(x, z, lsb, capture=capture, created=created)
        if "y_axis" in d:
            y = np.array(_vec3(d["y_axis"], f"{where}.y_axis"))
            err = float(np.max(np.abs(y - np.array(cal.y_axis))))
            if err > Y_AXIS_TOL:
                raise ConfigError(f"{where}: y_axis is not z_axis x x_axis (off by {err:.2e}): "
                                  "the file was edited or corrupted")
        return cal

    def save(self, path, wheel: str) -> None:
        """Writes (or updates) this wheel's entry in a calibration file, atomically.

        An existing file must be a valid calibration file: it is never silently overwritten.
        """
        _check_wheel(wheel, "save")
        path = Path(path)
        wheels = load_calibrations(path) if path.exists() else {}
        wheels[wheel] = self
        save_calibrations(path, wheels)

    @classmethod
    def load(cls, path, wheel: str) -> Calibration:
        """This wheel's calibration from a file (validated; ConfigError says what is wrong)."""
        _check_wheel(wheel, "load")
        wheels = load_calibrations(path)
        if wheel not in wheels:
            raise ConfigError(f"{path}: no calibration for wheel {wheel} (file has: {', '.join(wheels)})")
        return wheels[wheel]


def _check_wheel(wheel: str, what: str) -> None:
    if wheel not in WHEELS:
        raise ConfigError(f"{what}: wheel must be one of {', '.join(WHEELS)}, got {wheel!r}")


def save_calibrations(path, wheels: Mapping[str, Calibration]) -> None:
    """Writes a whole calibration file (JSON, format/version keyed) atomically."""
    for w in wheels:
        _check_wheel(w, "save")
    doc = {
        "format": FORMAT,
        "version": VERSION,
        "wheels": {w: wheels[w].to_dict() for w in WHEELS if w in wheels},
    }
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent or ".")
    try:
        with os.fdopen(fd, "w") as fh:
            json.dump(doc, fh, indent=2)
            fh.write("\n")
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def load_calibrations(path) -> dict[str, Calibration]:
    """Every wheel's calibration in a file; ConfigError names the file, the key and the problem."""
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ConfigError(f"{path}: calibration file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read calibration file: {exc}") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{path}: not JSON ({exc})") from None
    except RecursionError:
        raise ConfigError(f"{path}: not a calibration file (JSON nested too deeply)") from None
    if not isinstance(doc, dict):
        raise ConfigError(f"{path}: expected a JSON object at the top level")
    if doc.get("format") != FORMAT:
        raise ConfigError(f"{path}: not a camber calibration file (format must be {FORMAT!r}, "
                          f"got {doc.get('format')!r})")
    version = doc.get("version")
    if not isinstance(version, int) or isinstance(version, bool):
        raise ConfigError(f"{path}: version must be an integer, got {version!r}")
    if version != VERSION:
        newer = " (written by a newer vehest-can)" if version > VERSION else ""
        raise ConfigError(f"{path}: unsupported version {version}{newer}; this reads version {VERSION}")
    unknown = sorted(set(doc) - {"format", "version", "wheels"})
    if unknown:
        raise ConfigError(f"{path}: unknown top-level key(s) {', '.join(unknown)}")
    wheels = doc.get("wheels")
    if not isinstance(wheels, dict) or not wheels:
        raise ConfigError(f"{path}: 'wheels' must be a non-empty object keyed by {', '.join(WHEELS)}")
    out = {}
    for w, entry in wheels.items():
        if w not in WHEELS:
            raise ConfigError(f"{path}: unknown wheel {w!r}; wheels are {', '.join(WHEELS)}")
        out[w] = Calibration.from_dict(entry, where=f"{path}: wheels.{w}")
    return out


def calibrate(x_down, z_down, lsb_g=DEFAULT_LSB_G, limits: CalibrationLimits | None = None) -> Calibration:
    """eq. 7-19 in the firmware: captures (raw counts, (N, 3)) with the device's x axis down and
    with its z axis down -> Calibration. Raises CaptureError with the reason when a capture is
    too short, saturated, moving (spread), of the wrong magnitude, or the axes are not square."""
    limits = limits or CalibrationLimits()
    lim = limits._to_c()
    lsb = _check_lsb(lsb_g, "calibrate")
    caps = []
    n_sat = []
    for name, samples in (("x-down", x_down), ("z-down", z_down)):
        raw = _as_counts(samples, f"{name} capture", CaptureError)
        cap = ffi.new("vh_camber_capture_t *")
        check(lib.vh_camber_capture_init(cap, lsb), "camber capture init")
        check(lib.vh_camber_capture_add_n(cap, len(raw), ffi.from_buffer("int16_t[]", raw)), f"{name} capture")
        caps.append(cap)
        n_sat.append(int(np.sum(np.any((raw == 32767) | (raw == -32768), axis=1))))
    cal = ffi.new("vh_camber_cal_t *")
    rep = ffi.new("vh_camber_cal_report_t *")
    st = CalStatus(lib.vh_camber_calibrate(cal, rep, caps[0], caps[1], lim))
    if st != CalStatus.OK:
        raise CaptureError(_capture_message(rep, st, limits, (n_sat[0], n_sat[1])))
    capture = {
        "n": [int(rep.n[0]), int(rep.n[1])],
        "std_g": [float(rep.std_g[0]), float(rep.std_g[1])],
        "mag_g": [float(rep.mag_g[0]), float(rep.mag_g[1])],
        "x_dot_z": float(rep.x_dot_z),
    }
    return Calibration(
        tuple(cal.x_axis), tuple(cal.z_axis), lsb, capture=capture,
        created=datetime.now(UTC).isoformat(timespec="seconds"),
    )


@dataclass(frozen=True)
class Result:
    """One inspection result. theta/psi/bound (rad) are None unless reason is OK."""

    theta: float | None
    psi: float | None
    bound: float | None
    reason: Reason
    a_s_g: tuple[float, float, float] | None  # window mean in S (diagnostic)
    mag_g: float
    std_g: float
    n: int
    config: MeasureConfig = field(default_factory=MeasureConfig, repr=False, compare=False)

    @property
    def ok(self) -> bool:
        return self.reason == Reason.OK

    @property
    def theta_deg(self) -> float | None:
        return None if self.theta is None else math.degrees(self.theta)

    @property
    def psi_deg(self) -> float | None:
        return None if self.psi is None else math.degrees(self.psi)

    @property
    def bound_deg(self) -> float | None:
        return None if self.bound is None else math.degrees(self.bound)

    @property
    def message(self) -> str:
        c = self.config
        return {
            Reason.OK: "camber published",
            Reason.MOVING: f"window spread {self.std_g:.4f} g exceeds {c.std_max_g:.4f} g: vehicle or device moving",
            Reason.NOT_STATIONARY_FLAG: "the vehicle was not flagged stationary during the window",
            Reason.MAGNITUDE: (f"mean acceleration {self.mag_g:.4f} g is more than {c.mag_tol_g:.4f} g from 1 g: "
                               "not at rest on a level floor, or a sensor fault"),
            Reason.TOO_FEW_SAMPLES: f"{self.n} samples in the window; at least {c.min_samples} are needed",
            Reason.NOT_CALIBRATED: "no valid chip-in-device calibration loaded",
            Reason.SATURATED: "a sample hit the int16 limits (sensor saturated)",
        }[self.reason]


def _result(r, config: MeasureConfig) -> Result:
    reason = Reason(r.reason)
    ok = reason == Reason.OK
    has_a = reason not in (Reason.NOT_CALIBRATED, Reason.TOO_FEW_SAMPLES)
    return Result(
        theta=float(r.theta_rad) if ok else None,
        psi=float(r.psi_rad) if ok else None,
        bound=float(r.bound_rad) if ok else None,
        reason=reason,
        a_s_g=tuple(float(v) for v in r.a_s_g) if has_a else None,  # type: ignore[arg-type]
        mag_g=float(r.mag_g),
        std_g=float(r.std_g),
        n=int(r.n),
        config=config,
    )


def _instance(calibration: Calibration | None, config: MeasureConfig, window: int):
    if not (isinstance(config.min_samples, int) and 2 <= config.min_samples <= N_MAX):
        raise ConfigError(f"min_samples must be an integer in 2..{N_MAX}, got {config.min_samples!r}")
    if not (isinstance(window, int) and config.min_samples <= window <= N_MAX):
        raise ConfigError(f"window must be an integer in min_samples..{N_MAX}, got {window!r}")
    _check_positive(config, ("mag_tol_g", "std_max_g"))
    cfg = replace(config, window=window).to_c()
    inst = ffi.new("vh_camber_t *")
    c_cal = calibration._to_c() if calibration is not None else ffi.NULL
    check(lib.vh_camber_init(inst, cfg, c_cal), "camber init")
    return inst


def _stationary_array(stationary, n: int):
    if isinstance(stationary, (bool, np.bool_)):
        return ffi.NULL if stationary else np.zeros(n, dtype=np.uint8)
    arr = np.asarray(stationary)
    if arr.shape != (n,):
        raise ConfigError(f"stationary must be a bool or an array of {n} flags, got shape {arr.shape}")
    return np.ascontiguousarray(arr.astype(bool), dtype=np.uint8)


def measure_windows(samples, calibration: Calibration | None, stationary: bool | Iterable[bool] = True,
                    config: MeasureConfig | None = None) -> list[Result]:
    """Runs the firmware over consecutive windows of config.window samples (a trailing partial
    window is dropped, as the firmware would still be filling it)."""
    config = config or MeasureConfig()
    raw = _as_counts(samples, "samples", max_n=None)
    inst = _instance(calibration, config, config.window)
    flags = _stationary_array(stationary, len(raw))
    cap = len(raw) // config.window
    out = ffi.new("vh_camber_result_t[]", max(cap, 1))
    flag_ptr = flags if flags is ffi.NULL else ffi.from_buffer("uint8_t[]", flags)
    done = lib.vh_camber_run(inst, len(raw), ffi.from_buffer("int16_t[]", raw), flag_ptr, out, cap)
    return [_result(out[i], config) for i in range(min(done, cap))]


def measure(samples, calibration: Calibration | None, stationary: bool | Iterable[bool] = True,
            config: MeasureConfig | None = None) -> Result:
    """One inspection over all of ``samples`` (raw counts, (N, 3)) as a single window.

    ``stationary`` is the caller's at-rest flag, one bool or one per sample. ``calibration``
    None gives Reason.NOT_CALIBRATED (as the ECU before a calibration file is loaded).
    """
    config = config or MeasureConfig()
    raw = _as_counts(samples, "samples")
    n = len(raw)
    inst = _instance(calibration, config, max(n, config.min_samples))
    flags = _stationary_array(stationary, n)
    flag_ptr = flags if flags is ffi.NULL else ffi.from_buffer("uint8_t[]", flags)
    out = ffi.new("vh_camber_result_t[1]")
    done = lib.vh_camber_run(inst, n, ffi.from_buffer("int16_t[]", raw), flag_ptr, out, 1) if n else 0
    if done == 0:
        lib.vh_camber_evaluate(inst, out)
    return _result(out[0], config)


def worst_case_error(theta: float, psi: float, da_g=DEFAULT_LSB_G, g: float = 1.0) -> float:
    """eq. 22 in the firmware (float32): worst-case |d theta| in rad for per-axis errors da_g."""
    da = _check_lsb(da_g, "worst_case_error")
    return float(lib.vh_camber_bound(theta, psi, da, g))


class CamberNode:
    """The simulated wheel-mounted inspection device (firmware_sim/vh_cambernode)."""

    POSES = {"wheel": lib.VH_CAMBERNODE_WHEEL, "x_down": lib.VH_CAMBERNODE_X_DOWN,
             "z_down": lib.VH_CAMBERNODE_Z_DOWN}

    def __init__(self, theta: float = 0.0, psi: float = 0.0, chip=(0.0, 0.0, 0.0), lsb_g=DEFAULT_LSB_G,
                 noise_std_g: float = 0.004, bias_g=(0.0, 0.0, 0.0), gravity_g: float = 1.0, seed: int = 1):
        cfg = ffi.new("vh_cambernode_config_t *")
        lib.vh_cambernode_config_default(cfg)
        cfg.theta_rad, cfg.psi_rad = theta, psi
        cfg.chip_rad = list(_vec3(list(chip), "chip"))
        cfg.lsb_g = list(_check_lsb(lsb_g, "CamberNode"))
        cfg.noise_std_g = noise_std_g
        cfg.bias_g = list(_vec3(list(bias_g), "bias_g"))
        cfg.gravity_g = gravity_g
        cfg.seed = seed
        self._node = ffi.new("vh_cambernode_t *")
        check(lib.vh_cambernode_init(self._node, cfg), "camber node init")

    def set_wheel(self, theta: float, psi: float) -> None:
        check(lib.vh_cambernode_set_wheel(self._node, theta, psi), "camber node set_wheel")

    def set_disturbance(self, accel_s_g) -> None:
        lib.vh_cambernode_set_disturbance(self._node, list(_vec3(list(accel_s_g), "disturbance")))

    def capture(self, n: int, pose: str = "wheel") -> np.ndarray:
        """n raw samples (int16, (n, 3)) in a pose: 'wheel', 'x_down' or 'z_down'."""
        if pose not in self.POSES:
            raise ConfigError(f"pose must be one of {', '.join(self.POSES)}, got {pose!r}")
        check(lib.vh_cambernode_set_pose(self._node, self.POSES[pose]), "camber node pose")
        out = np.empty((n, 3), dtype=np.int16)
        lib.vh_cambernode_run(self._node, n, ffi.from_buffer("int16_t[]", out))
        return out

    def reading_s(self, pose: str = "wheel") -> np.ndarray:
        """Noise-free reading in S (g) for a pose: the truth."""
        check(lib.vh_cambernode_set_pose(self._node, self.POSES[pose]), "camber node pose")
        r = ffi.new("double[3]")
        lib.vh_cambernode_reading_s(self._node, r)
        return np.array(list(r))

    @property
    def true_m(self) -> np.ndarray:
        """The true eq. 19 M of the simulated chip (a_A = M a_S)."""
        m = ffi.new("double[9]")
        lib.vh_cambernode_true_m(self._node, m)
        return np.array(list(m)).reshape(3, 3)


__all__ = [
    "FORMAT", "VERSION", "WHEELS", "CaptureError", "Reason", "CalStatus", "CalibrationLimits",
    "MeasureConfig", "Calibration", "Result", "calibrate", "measure", "measure_windows",
    "worst_case_error", "save_calibrations", "load_calibrations", "CamberNode",
]


def load_into_ecu(ecu, calibrations: Mapping) -> None:
    """Load inspection-device calibrations ({wheel: Calibration}, e.g. from load_calibrations) into an
    ECU (:class:`~vehest_can.systems.ecu.Ecu`); they persist across ECU resets."""
    for wheel, cal in calibrations.items():
        check(lib.vh_camber_app_set_calibration(ffi.addressof(ecu.c.app, "camber"), WHEELS.index(wheel), cal._to_c()),
              f"camber calibration of {wheel}")
