"""Scenarios: user-written TOML files that drive the driveline plant and its sensor node.

The schema is documented in ``docs/scenarios.md``. ``load_scenario`` checks every key (unknown
keys, types, ranges, time profiles) and raises :class:`~vehest_can.errors.ScenarioError` whose
message names the file, the key as a dotted path and the problem. A loaded :class:`Scenario` is
immutable; it turns itself into the C structs (``plant_params``, ``node_config``) and into
ready-to-step instances (``make_plant``, ``make_node``).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, TypeVar

import numpy as np

from ..errors import ScenarioError
from ..paths import ShippedSet
from ..schema import Checker, Num, read_toml, type_name

#: Plant and sensor-node step [s]: one ECU tick (VH_TICK_US).
DT = 0.0005

#: the shipped driveline scenarios: inside the installed package, or firmware_sim/scenarios/ of a checkout
SCENARIOS = ShippedSet("scenarios", "firmware_sim/scenarios")
scenario_dir, list_scenarios, scenario_path = SCENARIOS.dir, SCENARIOS.names, SCENARIOS.path


# ---- schema --------------------------------------------------------------------------------

#: the top-level keys every system's scenario has
SCENARIO_TOP: dict[str, Any] = {
    "name": "string",
    "description": "string",
    "duration_s": Num(0.0, 3600.0, lo_open=True),
    "seed": Num(0, 2**64 - 1, integer=True),
    "initial_speed_kmh": Num(0.0, 250.0),
}
_TOP = SCENARIO_TOP
_TABLES = ("driver", "road", "vehicle", "sensors", "camber")

_DRIVER = {"gear": Num(0, 5, integer=True)}  # plus "throttle", a profile
_ROAD = {
    # TOML key -> (vh_dlp_params_t field, range)
    "roughness_std_nm": ("road_std", Num(0.0, 2000.0)),
    "roughness_bandwidth_hz": ("road_bw", Num(0.0, 500.0, lo_open=True)),
}
# [vehicle] overrides: TOML key -> (vh_dlp_params_t field, range). The ranges are physical
# plausibility; the plant itself then refuses combinations its fixed step cannot resolve.
_VEHICLE = {
    "output_inertia_kgm2": ("jo", Num(0.008, 1.0)),
    "vehicle_inertia_kgm2": ("jv", Num(10.0, 5000.0)),
    "final_drive_ratio": ("rd", Num(0.1, 1.0)),
    "shaft_stiffness_nm_per_rad": ("ks", Num(100.0, 100000.0)),
    "shaft_damping_nms_per_rad": ("cs", Num(0.0, 100.0)),
    "wheel_radius_m": ("rt", Num(0.15, 0.6)),
    "rolling_resistance": ("mu_r", Num(0.0, 0.1)),
    "air_density_kg_m3": ("rho", Num(0.0, 2.0)),
    "drag_coefficient": ("ca", Num(0.0, 2.0)),
    "frontal_area_m2": ("area", Num(0.0, 10.0)),
    "engine_inertia_kgm2": ("je", Num(0.02, 2.0)),
    "engine_peak_torque_nm": ("te_peak", Num(10.0, 1000.0)),
    "idle_speed_rad_s": ("w_idle", Num(40.0, 150.0)),
}
_GEAR_RATIO = Num(0.2, 3.0)  # each of vehicle.gear_ratios, w_o = R_i w_t
# [sensors] noise standard deviations: TOML key -> (vh_dls_config_t array, channel indices, range)
_SENSORS = {
    "out_shaft_speed_std_rad_s": ("noise_std", (0,), Num(0.0, 100.0)),
    "wheel_speed_std_rad_s": ("noise_std", (1, 2), Num(0.0, 100.0)),
    "shaft_torque_std_nm": ("noise_std", (3,), Num(0.0, 1000.0)),
    "engine_speed_std_rad_s": ("noise_std", (4,), Num(0.0, 100.0)),
    "turbine_speed_std_rad_s": ("noise_std", (5,), Num(0.0, 100.0)),
}
# [camber]: the four wheel-mounted inspection devices of seed 002 (FL, FR, RL, RR)
_CAMBER_POSES = {"wheel": 0, "x_down": 1, "z_down": 2}
_CAMBER = {
    "theta_deg": Num(-15.0, 15.0),    # true camber per wheel
    "psi_deg": Num(-45.0, 45.0),      # device misalignment yaw per wheel
    "chip_deg": Num(-10.0, 10.0),     # chip rotation in the device about x, y, z, per wheel
    "lsb_mg": Num(0.1, 100.0, lo_open=False),
    "noise_mg": Num(0.0, 100.0),
}


def derived_seed(seed: int, salt: int) -> int:
    """A node's own random stream from the scenario's seed (odd multiplier: a bijection; `salt` keeps the
    streams of different nodes apart)."""
    return (seed * 0x9E3779B97F4A7C15 + salt) % 2**64


@dataclass(frozen=True)
class ScenarioBase:
    """What every system's scenario dataclass has alike: the fields of SCENARIO_TOP (first, in its
    order), steps, the sensor node's seed, configuration and instance, the plant-alone run. A subclass
    adds its fields (``sensors`` and ``path`` among them), names its C types and [sensors] table, and
    supplies ``make_plant`` and ``_run`` (the plant's own run call)."""

    name: str
    description: str
    duration_s: float
    seed: int
    initial_speed_kmh: float
    #: the sensor node's C prefix (``<_NODE>_t``, ``<_NODE>_init``), the plant's truth struct, the node seed's salt
    _NODE: ClassVar[str]
    _TRUTH: ClassVar[str]
    _SEED_SALT: ClassVar[int]
    #: its [sensors] table: TOML key -> (config array, channels, range)
    _SENSORS: ClassVar[dict[str, tuple]]

    def __init_subclass__(cls, *, node: str, truth: str, seed_salt: int, sensors: dict[str, tuple], **kw: Any) -> None:
        super().__init_subclass__(**kw)
        cls._NODE, cls._TRUTH, cls._SEED_SALT, cls._SENSORS = node, truth, seed_salt, sensors

    if TYPE_CHECKING:  # fields of each subclass, after its own (they have defaults, the fields above none)
        @property
        def sensors(self) -> tuple[tuple[str, float], ...]: ...  # [sensors] (key, value) pairs

        @property
        def path(self) -> Path | None: ...  # the file

    @property
    def n_steps(self) -> int:
        """Plant steps of DT in duration_s."""
        return int(round(self.duration_s / DT))

    @property
    def node_seed(self) -> int:
        """Seed of the sensor node's random stream, derived from ``seed``."""
        return derived_seed(self.seed, self._SEED_SALT)

    def make_plant(self, ffi, lib) -> Any:
        raise NotImplementedError

    def node_config(self, ffi, lib):
        """A ``<_NODE>_config_t *``: the sensor node's defaults with this scenario's sensors and seed."""
        cfg = ffi.new(f"{self._NODE}_config_t *")
        getattr(lib, f"{self._NODE}_config_default")(cfg)
        set_channels(cfg, self.sensors, self._SENSORS)
        cfg.seed = self.node_seed
        return cfg

    def _run(self, ffi, lib, plant, n: int, out) -> None:
        raise NotImplementedError

    def make_node(self, ffi, lib):
        """An initialised sensor node (``<_NODE>_t *``) of ``node_config``."""
        n = ffi.new(f"{self._NODE}_t *")
        if getattr(lib, f"{self._NODE}_init")(n, self.node_config(ffi, lib)) != lib.VH_OK:
            raise ScenarioError(f"{self._where()}: sensors: the sensor node refuses this configuration")
        return n

    def run_truth(self, ffi, lib) -> np.ndarray:
        """The plant alone over the whole scenario: the truth of every step as a numpy record array."""
        from ..native import struct_array

        p = self.make_plant(ffi, lib)
        n = self.n_steps
        out = ffi.new(f"{self._TRUTH}[]", n)
        self._run(ffi, lib, p, n, out)
        return struct_array(self._TRUTH, out, n)

    def car_steps(self, duration_s: float | None = None) -> int:
        """The steps a car runs: the whole scenario, or duration_s worth (not more than the whole)."""
        n = self.n_steps if duration_s is None else int(round(duration_s / DT))
        if not 0 < n <= self.n_steps:
            raise ScenarioError(f"{self._where()}: duration must be in (0, {self.duration_s}] s")
        return n

    def _where(self) -> str:
        return str(self.path) if self.path is not None else f"scenario {self.name!r}"


@dataclass(frozen=True)
class Camber:
    theta_deg: tuple[float, float, float, float]
    psi_deg: tuple[float, float, float, float]
    chip_deg: tuple[tuple[float, float, float], ...]
    lsb_mg: float = 4.0
    noise_mg: float = 4.0
    pose: str = "wheel"


@dataclass(frozen=True)
class Scenario(ScenarioBase, node="vh_dls", truth="vh_dlp_truth_t", seed_salt=0x444C53, sensors=_SENSORS):
    """One validated scenario. Times in s, speeds in rad/s unless the name says otherwise."""

    gear: int
    throttle: tuple[tuple[float, float], ...]  # (t, value) points, t strictly increasing
    road_std_nm: float
    road_bandwidth_hz: float
    vehicle: tuple[tuple[str, Any], ...] = ()  # [vehicle] overrides as written (TOML key, value)
    sensors: tuple[tuple[str, float], ...] = ()  # every [sensors] key, defaults filled in
    camber: Camber | None = None  # [camber]: inspection devices clamped on
    path: Path | None = None

    def times(self) -> np.ndarray:
        """Time after each plant step: DT, 2 DT, ..., n_steps DT."""
        return (np.arange(self.n_steps) + 1) * DT

    def throttle_at(self, t) -> np.ndarray:
        """Throttle at times t: piecewise linear, held before the first and after the last point."""
        ts = np.array([p[0] for p in self.throttle], dtype=float)
        vs = np.array([p[1] for p in self.throttle], dtype=float)
        return np.interp(np.asarray(t, dtype=float), ts, vs)

    def plant_params(self, ffi, lib):
        """A ``vh_dlp_params_t *``: the plant's defaults with this scenario's road and vehicle."""
        prm = ffi.new("vh_dlp_params_t *")
        lib.vh_dlp_params_default(prm)
        prm.road_std = self.road_std_nm
        prm.road_bw = self.road_bandwidth_hz
        for key, value in self.vehicle:
            if key == "gear_ratios":
                for i, r in enumerate(value):
                    prm.ri[i] = r
            else:
                setattr(prm, _VEHICLE[key][0], value)
        return prm

    def camber_configs(self, ffi, lib):
        """(``vh_cambernode_config_t[4]``, pose) for the inspection devices, or None."""
        if self.camber is None:
            return None
        cfgs = ffi.new("vh_cambernode_config_t[4]")
        for i in range(4):
            lib.vh_cambernode_config_default(ffi.addressof(cfgs[i]))
            cfgs[i].theta_rad = np.radians(self.camber.theta_deg[i])
            cfgs[i].psi_rad = np.radians(self.camber.psi_deg[i])
            cfgs[i].chip_rad = [float(np.radians(a)) for a in self.camber.chip_deg[i]]
            cfgs[i].lsb_g = [self.camber.lsb_mg * 1e-3] * 3
            cfgs[i].noise_std_g = self.camber.noise_mg * 1e-3
            cfgs[i].seed = (self.node_seed + 7919 * (i + 1)) % 2**64 or 1
        return cfgs, _CAMBER_POSES[self.camber.pose]

    def make_plant(self, ffi, lib):
        """An initialised ``vh_dlp_t *`` at the initial speed in the scenario's gear."""
        p = ffi.new("vh_dlp_t *")
        if lib.vh_dlp_init(p, self.plant_params(ffi, lib), self.seed) != lib.VH_OK:
            raise ScenarioError(f"{self._where()}: vehicle: the plant refuses these parameters "
                                "(a mode too fast for its 0.5 ms step)")
        if self.initial_speed_kmh > 0.0:
            lib.vh_dlp_set_rolling(p, self.initial_speed_kmh / 3.6, self.gear)
        return p

    def _run(self, ffi, lib, plant, n: int, out) -> None:
        thr = np.ascontiguousarray(self.throttle_at(self.times()))
        lib.vh_dlp_run(plant, n, ffi.cast("double *", ffi.from_buffer(thr)), self.gear, out)


def truth_dtype(ffi) -> np.dtype:
    """numpy dtype laid out like ``vh_dlp_truth_t`` (offsets from the compiler, via cffi)."""
    from ..native import struct_dtype

    return struct_dtype("vh_dlp_truth_t")


def truth_to_numpy(ffi, truth_array, n: int) -> np.ndarray:
    """Copy n ``vh_dlp_truth_t`` from a cffi array into a numpy record array."""
    from ..native import struct_array

    return struct_array("vh_dlp_truth_t", truth_array, n)


# ---- loading -------------------------------------------------------------------------------

def _native():
    from ..native import ffi, lib  # the compiled core; imported late so the schema helpers need none
    return ffi, lib


def scenario_top(c: Checker, doc: dict, top: dict[str, Any], tables: tuple[str, ...]) -> dict[str, Any]:
    """The keys of a scenario document checked against ``top`` and ``tables``, and the fields every
    system's scenario has (name, description, duration_s, seed, initial_speed_kmh), read."""
    c.table(doc, "", set(top) | set(tables))
    for key in ("name", "duration_s"):
        if key not in doc:
            c.fail(key, "missing (required)")
    name = c.string(doc["name"], "name")
    if not name.strip():
        c.fail("name", "must not be empty")
    return {"name": name, "description": c.string(doc.get("description", ""), "description"),
            "duration_s": c.number(doc["duration_s"], "duration_s", SCENARIO_TOP["duration_s"]),
            "seed": c.number(doc.get("seed", 1), "seed", SCENARIO_TOP["seed"]),
            "initial_speed_kmh": c.number(doc.get("initial_speed_kmh", 0.0), "initial_speed_kmh",
                                          SCENARIO_TOP["initial_speed_kmh"])}


_S = TypeVar("_S")


def load_shipped(shipped: ShippedSet, name_or_path: str | Path, from_dict: Callable[[dict, Path], _S]) -> _S:
    """A scenario file (a path, or the name of one of `shipped`) read and validated by `from_dict`."""
    path = shipped.path(name_or_path)
    return from_dict(read_toml(path), path)


def set_channels(cfg, values, table: dict[str, tuple]) -> None:
    """A sensor node's per-channel settings: each (key, value) of `values` into the channels of the
    cfg array that ``table[key]`` names, ``(array, channels, range)``."""
    for key, value in values:
        array, chans, _ = table[key]
        for ch in chans:
            getattr(cfg, array)[ch] = value


def kind_checker(doc, path: str | Path, kinds: tuple[str, ...], expected: str, missing: str = "") -> Checker:
    """The Checker of a scenario document that must be a table whose ``kind`` is one of `kinds`:
    ``kind: missing`` when it has none and `missing` is given, else ``kind: must be <expected>, not ...``."""
    c = Checker(Path(path))
    if not isinstance(doc, dict):
        c.fail("", f"must be a TOML document (a table), not {type_name(doc)}")
    if doc.get("kind") not in kinds:
        if missing and "kind" not in doc:
            c.fail("kind", missing)
        c.fail("kind", f"must be {expected}, not {doc.get('kind')!r}")
    return c


def load_scenario(path: str | Path) -> Scenario:
    """Load and validate one scenario file (a path, or the name of a shipped scenario)."""
    return load_shipped(SCENARIOS, path, scenario_from_dict)


def scenario_from_dict(doc: dict, path: str | Path = "<scenario>") -> Scenario:
    """Validate an already parsed TOML document (``path`` only names it in errors)."""
    ffi, lib = _native()
    c = Checker(Path(path))
    top = scenario_top(c, doc, _TOP, _TABLES)

    if "driver" not in doc:
        c.fail("driver", "missing (required table with throttle and gear)")
    driver = c.table(doc["driver"], "driver", set(_DRIVER) | {"throttle"})
    for key in ("throttle", "gear"):
        if key not in driver:
            c.fail(f"driver.{key}", "missing (required)")
    throttle = c.profile(driver["throttle"], "driver.throttle", Num(0.0, 1.0))
    gear = c.number(driver["gear"], "driver.gear", _DRIVER["gear"])

    prm = ffi.new("vh_dlp_params_t *")
    lib.vh_dlp_params_default(prm)
    road = c.table(doc.get("road", {}), "road", _ROAD)
    road_v = {k: c.number(road[k], f"road.{k}", spec) if k in road else getattr(prm, field)
              for k, (field, spec) in _ROAD.items()}

    vehicle_doc = c.table(doc.get("vehicle", {}), "vehicle", set(_VEHICLE) | {"gear_ratios"})
    vehicle = []
    for k, v in vehicle_doc.items():
        if k == "gear_ratios":
            if not isinstance(v, list) or len(v) != 5:
                c.fail("vehicle.gear_ratios", "must be a list of 5 ratios R_i (gears 1..5, w_o = R_i w_t)")
            vehicle.append((k, tuple(c.number(r, f"vehicle.gear_ratios[{i}]", _GEAR_RATIO)
                                     for i, r in enumerate(v))))
        else:
            vehicle.append((k, c.number(v, f"vehicle.{k}", _VEHICLE[k][1])))

    cfg = ffi.new("vh_dls_config_t *")
    lib.vh_dls_config_default(cfg)
    sensors_doc = c.table(doc.get("sensors", {}), "sensors", _SENSORS)
    sensors = tuple((k, c.number(sensors_doc[k], f"sensors.{k}", spec) if k in sensors_doc
                     else getattr(cfg, array)[chans[0]]) for k, (array, chans, spec) in _SENSORS.items())

    camber = _camber(c, doc["camber"]) if "camber" in doc else None

    sc = Scenario(**top, gear=gear, throttle=throttle,
                  road_std_nm=road_v["roughness_std_nm"], road_bandwidth_hz=road_v["roughness_bandwidth_hz"],
                  vehicle=tuple(sorted(vehicle)), sensors=sensors, camber=camber, path=Path(path))
    probe = ffi.new("vh_dlp_t *")
    if lib.vh_dlp_init(probe, sc.plant_params(ffi, lib), sc.seed) != lib.VH_OK:
        c.fail("vehicle", "the plant refuses this combination of parameters (a mode too fast for "
                          "its 0.5 ms step: raise the inertias or the gear ratios, or lower stiffness or damping)")
    return sc


def _camber(c, doc) -> Camber:
    t = c.table(doc, "camber", set(_CAMBER) | {"pose"})
    for key in ("theta_deg", "psi_deg"):
        if key not in t:
            c.fail(f"camber.{key}", "missing (required: four values, FL FR RL RR)")

    def four(key, spec, width=None):
        v = t[key]
        if not isinstance(v, list) or len(v) != 4:
            c.fail(f"camber.{key}", "must be a list of 4 entries (FL, FR, RL, RR)")
        if width is None:
            return tuple(c.number(x, f"camber.{key}[{i}]", spec) for i, x in enumerate(v))
        out = []
        for i, row in enumerate(v):
            if not isinstance(row, list) or len(row) != width:
                c.fail(f"camber.{key}[{i}]", f"must be a list of {width} angles (about x, y, z)")
            out.append(tuple(c.number(x, f"camber.{key}[{i}][{j}]", spec) for j, x in enumerate(row)))
        return tuple(out)

    pose = c.string(t.get("pose", "wheel"), "camber.pose")
    if pose not in _CAMBER_POSES:
        c.fail("camber.pose", f"{pose!r}: expected one of {', '.join(_CAMBER_POSES)}")
    return Camber(
        theta_deg=four("theta_deg", _CAMBER["theta_deg"]),
        psi_deg=four("psi_deg", _CAMBER["psi_deg"]),
        chip_deg=four("chip_deg", _CAMBER["chip_deg"], 3) if "chip_deg" in t else ((0.0, 0.0, 0.0),) * 4,
        lsb_mg=c.number(t.get("lsb_mg", 4.0), "camber.lsb_mg", _CAMBER["lsb_mg"]),
        noise_mg=c.number(t.get("noise_mg", 4.0), "camber.noise_mg", _CAMBER["noise_mg"]),
        pose=pose,
    )


__all__ = ["DT", "Scenario", "load_scenario", "scenario_from_dict", "scenario_dir", "scenario_path",
           "list_scenarios", "truth_dtype", "truth_to_numpy", "Camber"]
