"""A car's data sheet as a file: the one description the ECU's calibration (every system's vehicle model)
and every plant read. TOML, checked by the project's schema reader; the schema and the CommonRoad mapping
are in ``docs/car.md``.

:func:`load_car` takes a path, a shipped car's name (``firmware_sim/cars/*.toml``, e.g. ``paper``) or one
of CommonRoad's parameter sets (``commonroad_vehicle1`` .. ``3``, from the ``commonroad-vehicle-models``
package); :func:`cars` lists the names. Every error is a :class:`~vehest_can.errors.ConfigError` naming the
file, the dotted key, the value and the allowed range."""
from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .errors import ConfigError
from .paths import ShippedSet
from .schema import Checker, Num, read_toml, type_name

#: the shipped car files
CARS = ShippedSet("cars", "firmware_sim/cars")
AXLES = ("front", "rear")

#: The data-sheet keys, shared with a scenario's [vehicle] table (vehest_can/sim/veh14.py builds it from
#: these): TOML key -> (vh_v14_params_t field, plausibility range).
DATA_SHEET: dict[str, tuple[str, Num]] = {
    "sprung_mass_kg": ("ms", Num(200.0, 5000.0)),
    "unsprung_mass_front_kg": ("m_uf", Num(10.0, 200.0)),
    "unsprung_mass_rear_kg": ("m_ur", Num(10.0, 200.0)),
    "roll_inertia_kgm2": ("ix", Num(50.0, 5000.0)),
    "pitch_inertia_kgm2": ("iy", Num(200.0, 20000.0)),
    "yaw_inertia_kgm2": ("iz", Num(200.0, 20000.0)),
    "cg_to_front_axle_m": ("lf", Num(0.3, 3.0)),
    "cg_to_rear_axle_m": ("lr", Num(0.3, 3.0)),
    "cg_height_m": ("h", Num(0.2, 1.5)),
    "half_track_front_m": ("tf", Num(0.4, 1.2)),
    "half_track_rear_m": ("tr", Num(0.4, 1.2)),
    "roll_centre_height_front_m": ("hf", Num(0.0, 0.4)),
    "roll_centre_height_rear_m": ("hr", Num(0.0, 0.4)),
    "wheel_radius_m": ("rw", Num(0.15, 0.6)),
    "wheel_inertia_kgm2": ("iw", Num(0.3, 20.0)),
    "spring_rate_front_n_per_m": ("k_f", Num(5e3, 3e5)),
    "spring_rate_rear_n_per_m": ("k_r", Num(5e3, 3e5)),
    "tyre_stiffness_n_per_m": ("kt", Num(5e4, 2e6)),
    "tyre_damping_ns_per_m": ("ct", Num(0.0, 5e3)),
    "air_density_kg_m3": ("rho", Num(0.0, 2.0)),
    "drag_area_m2": ("cda", Num(0.0, 5.0)),
}
#: optional keys and their values when absent (no tyre damping, no drag)
_OPTIONAL = {"tyre_damping_ns_per_m": 0.0, "air_density_kg_m3": 1.2, "drag_area_m2": 0.0}
# per axle, one of two forms each
_ROLL_STIFFNESS = Num(1e3, 1e6)          # suspension and tyres in series [N m/rad] (the paper's k_phi)
_BAR = Num(-1e6, 1e6)                    # anti-roll bar [N m/rad]; negative allowed (CommonRoad's)
_ROLL_DAMPING = Num(0.0, 1e5, lo_open=True)  # [N m s/rad] (the paper's c_phi); the roll UKF needs dampers
_DAMPER = Num(0.0, 2e4, lo_open=True)        # per corner [N s/m]
_E = Num(0.05, 1.5)                      # the SKFMEC's roll axis to CG distance, where a paper prints it
_COEF = Num(-1e6, 1e6)
_AXLE_KEYS = {f"{form}_{axle}_{unit}" for axle in AXLES for form, unit in (
    ("roll_stiffness", "nm_per_rad"), ("anti_roll_bar", "nm_per_rad"), ("roll_damping", "nms_per_rad"),
    ("damper_rate", "ns_per_m"))}
_TOP = {"name", "description", "roll_axis_to_cg_m", "tyre", *DATA_SHEET, *_AXLE_KEYS}
_TYRE_KEYS = {"lateral_coefficients": "a", "longitudinal_coefficients": "b"}
#: [tyre] of another form: a PAC2002 set with load-proportional slip stiffnesses (CommonRoad's tyre), as
#: published: p_cy1, p_dy1, p_ey1, p_ky1, p_cx1, p_dx1, p_ex1, p_kx1 (p_ky1's sign is the convention's)
_PAC_KEY, _PAC_N = "pac2002_coefficients", 8
_KLT_KEY, _KLT = "lateral_compliance_m_per_n", Num(0.0, 1e-3)
#: relative size below which a bar is rounding residue of k_phi <-> bar (as the plant, vh_veh14.c)
BAR_RESIDUE = 1e-9


@dataclass(frozen=True)
class CarFile:
    """One car, validated. Per axle the file gives the roll stiffness or the anti-roll bar, and the roll
    damping or the damper rate; the methods give each in both forms (the plant's formulas)."""

    name: str
    description: str
    path: Path | None
    sprung_mass_kg: float
    unsprung_mass_front_kg: float      # per corner
    unsprung_mass_rear_kg: float
    roll_inertia_kgm2: float           # sprung mass, about its CG
    pitch_inertia_kgm2: float
    yaw_inertia_kgm2: float
    cg_to_front_axle_m: float
    cg_to_rear_axle_m: float
    cg_height_m: float                 # sprung CG
    half_track_front_m: float
    half_track_rear_m: float
    roll_centre_height_front_m: float
    roll_centre_height_rear_m: float
    wheel_radius_m: float
    wheel_inertia_kgm2: float
    spring_rate_front_n_per_m: float   # at the wheel, per corner
    spring_rate_rear_n_per_m: float
    tyre_stiffness_n_per_m: float
    tyre_damping_ns_per_m: float = 0.0
    air_density_kg_m3: float = 1.2
    drag_area_m2: float = 0.0
    roll_stiffness_front_nm_per_rad: float | None = None
    roll_stiffness_rear_nm_per_rad: float | None = None
    anti_roll_bar_front_nm_per_rad: float | None = None
    anti_roll_bar_rear_nm_per_rad: float | None = None
    roll_damping_front_nms_per_rad: float | None = None
    roll_damping_rear_nms_per_rad: float | None = None
    damper_rate_front_ns_per_m: float | None = None
    damper_rate_rear_ns_per_m: float | None = None
    roll_axis_to_cg_m: float | None = None   # the SKFMEC's e where a paper prints it; else h - h_ra
    lateral_coefficients: tuple[float, ...] | None = None       # [tyre]: 9 Magic Formula numbers
    longitudinal_coefficients: tuple[float, ...] | None = None
    pac2002_coefficients: tuple[float, ...] | None = None       # [tyre]: the PAC2002 form instead
    lateral_compliance_m_per_n: float = 0.0                      # [tyre]: the patch's shift per lateral force

    # ---- derived: the plant's formulas (firmware_sim/src/vh_veh14.c) ----

    def _axle(self, axle: str) -> tuple[float, float]:
        """(half-track, spring rate) of an axle."""
        if axle not in AXLES:
            raise ConfigError(f"axle {axle!r}: expected one of {AXLES}")
        return getattr(self, f"half_track_{axle}_m"), getattr(self, f"spring_rate_{axle}_n_per_m")

    def tyre_roll_stiffness(self, axle: str) -> float:
        """The tyres' own roll stiffness, 2 kt t² [N m/rad]."""
        t, _ = self._axle(axle)
        return 2.0 * self.tyre_stiffness_n_per_m * t * t

    def suspension_roll_stiffness(self, axle: str) -> float:
        """Springs and bar, 2 k t² + k_arb; from k_φ: 1/(1/k_φ − 1/(2 kt t²)) [N m/rad]."""
        t, k = self._axle(axle)
        kphi = getattr(self, f"roll_stiffness_{axle}_nm_per_rad")
        if kphi is not None:
            inv = 1.0 / kphi - 1.0 / self.tyre_roll_stiffness(axle)
            return 1.0 / inv if inv > 0.0 else -1.0
        return 2.0 * k * t * t + self.anti_roll_bar(axle)

    def roll_stiffness(self, axle: str) -> float:
        """k_φ of the axle, suspension and tyres in series [N m/rad]."""
        kphi = getattr(self, f"roll_stiffness_{axle}_nm_per_rad")
        if kphi is not None:
            return kphi
        return 1.0 / (1.0 / self.suspension_roll_stiffness(axle) + 1.0 / self.tyre_roll_stiffness(axle))

    def anti_roll_bar(self, axle: str) -> float:
        """k_arb = k_susp − 2 k t² [N m/rad] (0: no bar; a rounding residue is no bar)."""
        t, k = self._axle(axle)
        bar = getattr(self, f"anti_roll_bar_{axle}_nm_per_rad")
        if bar is not None:
            return bar
        if getattr(self, f"roll_stiffness_{axle}_nm_per_rad") is None:
            return 0.0
        ks = self.suspension_roll_stiffness(axle)
        bar = ks - 2.0 * k * t * t
        return 0.0 if abs(bar) <= BAR_RESIDUE * ks else bar

    def roll_damping(self, axle: str) -> float:
        """c_φ = 2 c t² [N m s/rad]."""
        t, _ = self._axle(axle)
        c = getattr(self, f"roll_damping_{axle}_nms_per_rad")
        return c if c is not None else 2.0 * getattr(self, f"damper_rate_{axle}_ns_per_m") * t * t

    def damper_rate(self, axle: str) -> float:
        """c = c_φ / (2 t²), per corner [N s/m]."""
        t, _ = self._axle(axle)
        c = getattr(self, f"damper_rate_{axle}_ns_per_m")
        return c if c is not None else getattr(self, f"roll_damping_{axle}_nms_per_rad") / (2.0 * t * t)

    @property
    def total_mass_kg(self) -> float:
        return self.sprung_mass_kg + 2.0 * self.unsprung_mass_front_kg + 2.0 * self.unsprung_mass_rear_kg

    @property
    def roll_axis_height_m(self) -> float:
        """The roll axis's height under the sprung CG, h_ra = hf + (hr − hf) lf / l."""
        lf, lr = self.cg_to_front_axle_m, self.cg_to_rear_axle_m
        hf, hr = self.roll_centre_height_front_m, self.roll_centre_height_rear_m
        return hf + (hr - hf) * lf / (lf + lr)

    @property
    def roll_lever_m(self) -> float:
        """e, roll axis to sprung CG: ``roll_axis_to_cg_m`` where given (a paper's printed figure), else h − h_ra."""
        return self.roll_axis_to_cg_m if self.roll_axis_to_cg_m is not None else self.cg_height_m - self.roll_axis_height_m

    def with_values(self, **values) -> CarFile:
        """A copy with some keys changed (e.g. a scenario's [vehicle] overrides), not re-checked."""
        return dataclasses.replace(self, **values)

    # ---- the plant ----

    def veh14_params(self, ffi, lib):
        """An initialised ``vh_v14_params_t *`` of this car; what the file does not say (relaxation, v_low,
        sub-steps, the tyre size and, without a [tyre] table, its coefficients) stays at the C defaults.
        A PAC2002 set replaces the Magic Formula 1987 tyre (the size factor does not apply to it)."""
        prm = ffi.new("vh_v14_params_t *")
        lib.vh_v14_params_default(prm)
        for key, (fname, _) in DATA_SHEET.items():
            setattr(prm, fname, getattr(self, key))
        prm.kphi_f, prm.kphi_r = self.roll_stiffness("front"), self.roll_stiffness("rear")
        prm.cphi_f, prm.cphi_r = self.roll_damping("front"), self.roll_damping("rear")
        for key, arr in _TYRE_KEYS.items():
            coef = getattr(self, key)
            if coef is not None:
                getattr(prm.tyre, arr)[0:9] = list(coef)
        if self.pac2002_coefficients is not None:  # the plant plays the car's tyre, as the ECU expects it
            prm.tyre.model = lib.VH_MFT_PAC2002
            prm.tyre.p[0:8] = list(self.pac2002_coefficients)
        return prm


# ---- reading ----------------------------------------------------------------------------------------

def _number(c: Checker, value, key: str, spec: Num) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        c.fail(key, f"{value!r} is {type_name(value)}, not a number: must be {spec.describe()}")
    return c.number(value, key, spec)


def car_from_dict(doc: dict, path: str | Path, name: str | None = None) -> CarFile:
    """Validate a parsed car document (``path`` names it in errors; ``name`` when the file has none)."""
    c = Checker(path, ConfigError)
    c.table(doc, "", _TOP)
    if "name" in doc:
        name = c.string(doc["name"], "name")
    if not name or not name.strip():
        c.fail("name", "missing (required: the car's name)")
    values: dict[str, Any] = {"name": name, "description": c.string(doc.get("description", ""), "description"),
                              "path": Path(path) if not str(path).startswith("<") else None}
    for key, (_, spec) in DATA_SHEET.items():
        if key in doc:
            values[key] = _number(c, doc[key], key, spec)
        elif key in _OPTIONAL:
            values[key] = _OPTIONAL[key]
        else:
            c.fail(key, f"missing (required: {spec.describe()})")
    for axle in AXLES:
        for a, b, spec_a, spec_b, need in (
                (f"roll_stiffness_{axle}_nm_per_rad", f"anti_roll_bar_{axle}_nm_per_rad", _ROLL_STIFFNESS, _BAR, False),
                (f"roll_damping_{axle}_nms_per_rad", f"damper_rate_{axle}_ns_per_m", _ROLL_DAMPING, _DAMPER, True)):
            if a in doc and b in doc:
                c.fail(b, f"{doc[b]!r}: give either {a} or {b} for the {axle} axle, not both")
            if need and a not in doc and b not in doc:
                c.fail(a, f"missing: give {a} ({_ROLL_DAMPING.describe()}) or {b} ({_DAMPER.describe()}, per corner)")
            if a in doc:
                values[a] = _number(c, doc[a], a, spec_a)
            if b in doc:
                values[b] = _number(c, doc[b], b, spec_b)
    if "roll_axis_to_cg_m" in doc:
        values["roll_axis_to_cg_m"] = _number(c, doc["roll_axis_to_cg_m"], "roll_axis_to_cg_m", _E)
    tyre = c.table(doc.get("tyre", {}), "tyre", set(_TYRE_KEYS) | {_PAC_KEY, _KLT_KEY})
    if _PAC_KEY in tyre:
        v = tyre[_PAC_KEY]
        if not isinstance(v, list) or len(v) != _PAC_N:
            c.fail(f"tyre.{_PAC_KEY}", f"{v!r}: must be a list of {_PAC_N} numbers (p_cy1, p_dy1, p_ey1, p_ky1, "
                                       f"p_cx1, p_dx1, p_ex1, p_kx1)")
        if "lateral_coefficients" in tyre or "longitudinal_coefficients" in tyre:
            c.fail(f"tyre.{_PAC_KEY}", "one tyre per car: give the 1987 coefficients or the PAC2002 set, not both")
        pac = tuple(_number(c, x, f"tyre.{_PAC_KEY}[{i}]", _COEF) for i, x in enumerate(v))
        for i in (0, 1, 4, 5):
            if not pac[i] > 0.0:
                c.fail(f"tyre.{_PAC_KEY}[{i}]", f"{pac[i]!r}: the shape and peak factors must be positive")
        for i in (2, 6):
            if not pac[i] < 1.0:
                c.fail(f"tyre.{_PAC_KEY}[{i}]", f"{pac[i]!r}: the curvature factor must be below 1")
        for i in (3, 7):
            if pac[i] == 0.0:
                c.fail(f"tyre.{_PAC_KEY}[{i}]", "the slip stiffness factor must not be 0")
        values[_PAC_KEY] = pac
    if _KLT_KEY in tyre:
        values[_KLT_KEY] = _number(c, tyre[_KLT_KEY], f"tyre.{_KLT_KEY}", _KLT)
    for key in _TYRE_KEYS:
        if key in tyre:
            v = tyre[key]
            if not isinstance(v, list) or len(v) != 9:
                c.fail(f"tyre.{key}", f"{v!r}: must be a list of 9 Magic Formula coefficients (C, then 1..8 as published)")
            values[key] = tuple(_number(c, x, f"tyre.{key}[{i}]", _COEF) for i, x in enumerate(v))
    car = CarFile(**values)
    _check_whole(c, car)
    return car


def _check_whole(c: Checker, car: CarFile) -> None:
    """What the ranges of single keys cannot say: the combination, each refusal naming a key."""
    for hk in ("roll_centre_height_front_m", "roll_centre_height_rear_m"):
        if not getattr(car, hk) < car.cg_height_m:
            c.fail(hk, f"{getattr(car, hk)!r} is out of range: the roll centre must be below the sprung CG "
                       f"(cg_height_m = {car.cg_height_m:g} m)")
    for axle in AXLES:
        t, k = car._axle(axle)
        tyres = car.tyre_roll_stiffness(axle)
        kphi = getattr(car, f"roll_stiffness_{axle}_nm_per_rad")
        if kphi is not None and not kphi < tyres:
            c.fail(f"roll_stiffness_{axle}_nm_per_rad",
                   f"{kphi!r} is out of range: must be below the tyres' own roll stiffness 2 kt t^2 = {tyres:.6g} "
                   f"(tyres and suspension in series)")
        bar = getattr(car, f"anti_roll_bar_{axle}_nm_per_rad")
        if bar is not None and not 2.0 * k * t * t + bar > 0.0:
            c.fail(f"anti_roll_bar_{axle}_nm_per_rad",
                   f"{bar!r} is out of range: must be above -2 k t^2 = {-2.0 * k * t * t:.6g} (the axle's "
                   f"suspension roll stiffness must stay positive)")
    if car.roll_axis_to_cg_m is not None:
        geo = car.cg_height_m - car.roll_axis_height_m
        if abs(car.roll_axis_to_cg_m - geo) > 0.01:
            c.fail("roll_axis_to_cg_m", f"{car.roll_axis_to_cg_m!r} is out of range: must be within 0.01 m of "
                                        f"h - h_ra = {geo:.6g} m (the roll centres' axis under the CG)")


# ---- CommonRoad's parameter sets ---------------------------------------------------------------------

#: name -> (module of commonroad-vehicle-models, what CommonRoad says the car is)
COMMONROAD = {
    "commonroad_vehicle1": ("parameters_vehicle1", "Ford Escort"),
    "commonroad_vehicle2": ("parameters_vehicle2", "BMW 320i"),
    "commonroad_vehicle3": ("parameters_vehicle3", "VW Vanagon"),
    "commonroad_vehicle4": ("parameters_vehicle4", "semi-trailer truck"),
}


def commonroad_doc(name: str) -> dict:
    """A CommonRoad parameter set as a car document (docs/car.md has the mapping)."""
    import importlib

    module, what = COMMONROAD[name]
    try:
        mod = importlib.import_module(f"vehiclemodels.{module}")
    except ImportError as exc:
        raise ConfigError(f"{name}: needs the package commonroad-vehicle-models ({exc})") from None
    p = getattr(mod, module)()
    need = ("m_s", "m_uf", "m_ur", "I_Phi_s", "I_y_s", "I_z", "a", "b", "h_s", "T_f", "T_r", "h_raf", "h_rar",
            "K_sf", "K_sr", "K_sdf", "K_sdr", "K_tsf", "K_tsr", "K_zt", "R_w", "I_y_w")
    missing = [k for k in need if getattr(p, k, None) is None]
    if missing:
        raise ConfigError(f"{name}: CommonRoad's {module} ({what}) has no multi-body data ({', '.join(missing)} "
                          f"are None): not a car the plant or the ECU can run")
    return {
        "name": name,
        "description": f"CommonRoad {module} ({what}), commonroad-vehicle-models",
        "sprung_mass_kg": p.m_s, "unsprung_mass_front_kg": p.m_uf / 2.0, "unsprung_mass_rear_kg": p.m_ur / 2.0,
        "roll_inertia_kgm2": p.I_Phi_s, "pitch_inertia_kgm2": p.I_y_s, "yaw_inertia_kgm2": p.I_z,
        "cg_to_front_axle_m": p.a, "cg_to_rear_axle_m": p.b, "cg_height_m": p.h_s,
        "half_track_front_m": p.T_f / 2.0, "half_track_rear_m": p.T_r / 2.0,
        "roll_centre_height_front_m": p.h_raf, "roll_centre_height_rear_m": p.h_rar,
        "spring_rate_front_n_per_m": p.K_sf, "spring_rate_rear_n_per_m": p.K_sr,
        "damper_rate_front_ns_per_m": p.K_sdf, "damper_rate_rear_ns_per_m": p.K_sdr,
        # MB's torsion term adds K_ts (phi_body - phi_axle) to the roll moment: a restoring bar is negative there
        "anti_roll_bar_front_nm_per_rad": -p.K_tsf, "anti_roll_bar_rear_nm_per_rad": -p.K_tsr,
        "tyre_stiffness_n_per_m": p.K_zt, "wheel_radius_m": p.R_w, "wheel_inertia_kgm2": p.I_y_w,
        "drag_area_m2": 0.0,
        # the multi-body model's tyre (tire_model.py: PAC2002 with K_y = p_ky1 F_z, K_x = p_kx1 F_z) and its
        # lateral compliance K_lt (the contact patch's shift per lateral force)
        "tyre": {_PAC_KEY: [getattr(p.tire, f) for f in PAC_FIELDS], _KLT_KEY: p.K_lt},
    }


#: the PAC2002 fields of CommonRoad's tyre in the order of ``[tyre] pac2002_coefficients``
PAC_FIELDS = ("p_cy1", "p_dy1", "p_ey1", "p_ky1", "p_cx1", "p_dx1", "p_ex1", "p_kx1")


# ---- names ---------------------------------------------------------------------------------------------

def cars() -> list[str]:
    """The names :func:`load_car` takes besides paths: the shipped files and CommonRoad's sets."""
    return sorted(set(CARS.names()) | set(COMMONROAD))


@functools.cache
def _shipped(name: str) -> CarFile:
    if name in COMMONROAD:
        return car_from_dict(commonroad_doc(name), f"<{name}>", name)
    path = CARS.path(name)
    return car_from_dict(read_toml(path, ConfigError), path, name)


def load_car(spec: str | Path | CarFile, relative_to: str | Path | None = None) -> CarFile:
    """A car: a CarFile as it is, a shipped name (:func:`cars`), or a TOML file's path (relative to the
    folder `relative_to` when given, e.g. the scenario that names it)."""
    if isinstance(spec, CarFile):
        return spec
    text = str(spec)
    if text in COMMONROAD or (Path(text).suffix != ".toml" and len(Path(text).parts) == 1 and text in CARS.names()):
        return _shipped(text)
    path = Path(text)
    if relative_to is not None and not path.is_absolute():
        path = Path(relative_to) / path
    if not path.is_file():
        raise ConfigError(f"car {text!r}: neither a car file ({path}) nor a shipped car (one of: {', '.join(cars())})")
    return car_from_dict(read_toml(path, ConfigError), path, path.stem)


@functools.lru_cache(maxsize=1)
def paper_car() -> CarFile:
    """The paper's car (firmware_sim/cars/paper.toml): the C defaults, bit for bit."""
    return _shipped("paper")


def _spec(key: str) -> Num | None:
    if key in DATA_SHEET:
        return DATA_SHEET[key][1]
    return {"roll_stiffness": _ROLL_STIFFNESS, "anti_roll_bar": _BAR, "roll_damping": _ROLL_DAMPING,
            "damper_rate": _DAMPER, "roll_axis_to_cg_m": _E}.get(key.rsplit("_", 3)[0] if key != "roll_axis_to_cg_m" else key)


def blame(car: CarFile, what: str, accepts) -> str:
    """The message of a C refusal (`what`) of `car`: the key whose value from the paper's car makes
    ``accepts(car)`` true, with its value and documented range; per axle the two forms count as one key."""
    paper = paper_car()
    groups = [(k,) for k in DATA_SHEET] + [
        (f"{a}_{axle}_{u}", f"{b}_{axle}_{v}") for axle in AXLES
        for a, u, b, v in (("roll_stiffness", "nm_per_rad", "anti_roll_bar", "nm_per_rad"),
                           ("roll_damping", "nms_per_rad", "damper_rate", "ns_per_m"))] + [
        ("roll_axis_to_cg_m",), ("lateral_coefficients",), ("longitudinal_coefficients",), (_PAC_KEY,)]
    where = car.path or car.name
    for g in groups:
        if accepts(dataclasses.replace(car, **{k: getattr(paper, k) for k in g})):
            key = next((k for k in g if getattr(car, k) is not None), g[0])
            spec = _spec(key)
            rng = f"; documented range {spec.describe()}" if spec is not None else ""
            fix = ("without it the car is accepted" if getattr(paper, key) is None
                   else f"the paper's {getattr(paper, key)!r} is accepted")
            return (f"{where}: {key}: {getattr(car, key)!r} is refused by {what} together with the rest of this "
                    f"car ({fix}{rng})")
    return f"{where}: {what} refuses this car, and no single key's paper value makes it accept it"


def car_spec(car: CarFile) -> str:
    """What :func:`load_car` takes to load `car` again: a shipped car's name, else its file's absolute path."""
    if car.path is None or (car.path.stem == car.name and car.path.parent.resolve() == CARS.dir().resolve()):
        return car.name
    return str(car.path.resolve())


def car_of(scenario) -> CarFile | None:
    """The car a scenario names (a 14-DOF scenario, or one holding one as ``chassis``), or None."""
    car = getattr(scenario, "car", None)
    return car if isinstance(car, CarFile) else None


__all__ = ["CARS", "AXLES", "CarFile", "COMMONROAD", "car_from_dict", "commonroad_doc", "cars", "load_car",
           "paper_car", "car_of", "car_spec", "blame"]
