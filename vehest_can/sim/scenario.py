"""Scenarios: user-written TOML files, one kind per system (``kind = "<system>"`` at the top), each
driving one of the cars (:mod:`vehest_can.sim.powertrain`, :mod:`vehest_can.sim.veh14`).

What every kind shares is here: the top-level keys, the checks of the ``kind`` and of the top, the
per-channel sensor settings, the node seeds, and :class:`ScenarioBase`. A system's loader checks every
key (unknown keys, types, ranges, time profiles) and raises :class:`~vehest_can.errors.ScenarioError`
whose message names the file, the key as a dotted path and the problem. A loaded scenario is
immutable; it turns itself into the C structs (``plant_params``, ``node_config``) and into
ready-to-step instances (``make_plant``, ``make_node``). The schemas are in ``docs/scenarios.md``.
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

# ---- schema --------------------------------------------------------------------------------

#: the top-level keys every system's scenario has
SCENARIO_TOP: dict[str, Any] = {
    "name": "string",
    "description": "string",
    "duration_s": Num(0.0, 3600.0, lo_open=True),
    "seed": Num(0, 2**64 - 1, integer=True),
    "initial_speed_kmh": Num(0.0, 250.0),
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

    def __init_subclass__(cls, *, node: str = "", truth: str = "", seed_salt: int = 0,
                          sensors: dict[str, tuple] | None = None, **kw: Any) -> None:
        super().__init_subclass__(**kw)
        if node:  # else a scenario of the same car with more fields: its parent's
            cls._NODE, cls._TRUTH, cls._SEED_SALT, cls._SENSORS = node, truth, seed_salt, sensors or {}

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


@dataclass(frozen=True)
class Kind:
    """A system's scenario kind: its shipped folder (``firmware_sim/scenarios/<kind>/``, or the
    package's ``scenarios/<kind>/``) and the reader of its documents, ``read(doc, path, kind)``."""

    kind: str
    read: Callable[[dict, Path, str], Any]

    @property
    def shipped(self) -> ShippedSet:
        return ShippedSet(f"scenarios/{self.kind}", f"firmware_sim/scenarios/{self.kind}")

    def from_dict(self, doc: dict, path: str | Path = "<scenario>") -> Any:
        """Validate an already parsed TOML document (``path`` only names it in errors)."""
        return self.read(doc, Path(path), self.kind)

    def load(self, path: str | Path) -> Any:
        """Load and validate one scenario of this kind (a path, or the name of a shipped one)."""
        return load_shipped(self.shipped, path, self.from_dict)


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


__all__ = ["DT", "SCENARIO_TOP", "ScenarioBase", "Kind", "derived_seed", "scenario_top", "load_shipped", "set_channels",
           "kind_checker"]
