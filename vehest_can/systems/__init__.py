"""The systems: one estimator (or estimator + controller) of one paper each, one folder each.

Every folder ``systems/<name>/`` holds its array API over the C core, its independent numpy
reference, its scenario kind, its metrics, table and plots, and registers itself with one
:class:`System` object, ``SYSTEM`` in its ``system.py`` (apart from ``__init__.py``, so that the
ECU can use a system's array API without loading its registration). The demo (and whatever else runs
"every system") loops over :func:`registered`; adding a system is adding a folder.
"""
from __future__ import annotations

import importlib
import importlib.util
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple, Protocol

import numpy as np

from ..errors import ScenarioError
from ..schema import read_toml


@dataclass
class Setup:
    """What a system asks of the ECU before its scenarios run: extra ``vehest-can daemon`` arguments
    for the ECU process and the same configuration applied to a local :class:`~.ecu.Ecu`."""

    daemon_args: list[str] = field(default_factory=list)
    configure: Callable[[Any], None] = lambda ecu: None
    #: the car the ECU is calibrated for (``--car``, a :class:`~vehest_can.carfile.CarFile`); None: each
    #: scenario's own car, else the paper's. The off-line references of the metrics use the same.
    car: Any = None


class FaultCase(NamedTuple):
    """One row of a fault table: a fault (command-line form), the counters it must raise, wire options."""

    label: str
    fault: str
    expect: tuple[str, ...] = ()
    wire: dict = {}


class EcuEstimator(NamedTuple):
    """One estimator of a system as the ECU reports it: its name, the sensor frame it lives on, and
    how to read, from the ECU instance (``vh_ecu_t *``), its health (0 INIT, 1 OK, 2 DEGRADED, 3
    FAULT) and whether that frame has been heard since reset (never heard: not configured or
    absent, not failed)."""

    name: str
    input: str
    health: Callable[[Any], int]
    heard: Callable[[Any], bool]


class EcuCounters(NamedTuple):
    """A set of fault counters a system's application keeps in the ECU beside the ECU's own
    (VEHEST_Status): its name (e.g. the bus whose status frame carries them), the counter names
    and how to read the C struct holding them from the ECU instance (``vh_ecu_t *``)."""

    name: str
    names: tuple[str, ...]
    read: Callable[[Any], Any]


class FaultStudy(Protocol):
    """How ``vehest-can faults`` reads a system's response: which node the faults hit, which frame holds
    its estimates and how to decode health, validity and the estimate from that frame's payload."""

    sensor_node: str            # the car's node whose frames the faults hit
    sensor_message: str         # its sample frame (the age of the newest sample accepted)
    estimate_message: str       # the ECU frame kept per tick
    filters: tuple[str, ...]    # the estimators in that frame, by short name
    error_label: str            # the table's column of the first filter's error against the plant
    error_unit: str
    catalogue: tuple[FaultCase, ...]

    def health(self, est: np.ndarray, which: str) -> np.ndarray: ...    # (n,) 0 INIT .. 3 FAULT
    def valid(self, est: np.ndarray, which: str) -> np.ndarray: ...     # (n,) bool
    def estimate(self, est: np.ndarray, which: str) -> np.ndarray: ...  # (n,) in the unit of truth()
    def truth(self, car: Any) -> float: ...                             # the plant's value this tick


class Study(NamedTuple):
    """One of a system's design or validation studies (``vehest-can study SYSTEM.NAME``): the figures
    behind a table of its docs page. ``main`` names ``module:function``, imported only when it runs;
    the function takes the study's own arguments and the program name for its parser and returns an
    exit status."""

    name: str
    main: str
    help: str


@dataclass(frozen=True)
class CampaignRunner:
    """A campaign's run of a system: a scenario from a (varied) document, one in-process run to
    its figures as a nested dict of numbers (no plots: a campaign runs thousands)."""

    from_dict: Callable[[dict, Path], Any]
    run: Callable[[Any], dict]


class System(Protocol):
    #: the one name: folder, docs page, tests folder, plot folder
    name: str
    #: the scenario ``kind`` values it reads
    kinds: tuple[str, ...]
    #: its car runs on the wall clock (``demo --realtime``)
    realtime: bool
    #: its fault table (``vehest-can faults``); None: it has none
    faults: FaultStudy | None
    #: what ``vehest-can campaign`` runs (optional; a system without one takes no campaigns)
    campaign: CampaignRunner | None
    #: the DBC nodes its car plays on a bus (``vehest-can hil`` simulates them together, on one bus);
    #: a system without it cannot be simulated in a HIL rehearsal
    nodes: tuple[str, ...]
    #: its estimators in the ECU (health, heard), for the daemon's summary and the session stats
    estimators: tuple[EcuEstimator, ...]
    #: the counter sets its application keeps in the ECU (optional; none: it counts into the ECU's own)
    ecu_counters: tuple[EcuCounters, ...]
    #: its design and validation studies (``vehest-can study``; optional)
    studies: tuple[Study, ...]

    def configure_car(self, app: Any, car: Any) -> None:
        """(Optional.) Write a car (:class:`~vehest_can.carfile.CarFile`, :attr:`.ecu.EcuConfig.car`) into its
        application's vehicle model in ``app`` (``vh_ecu_config_t.app``), before ``configure_ecu``."""
        ...

    def configure_ecu(self, app: Any, part: Any) -> None:
        """(Optional.) Write its part of an :class:`~.ecu.EcuConfig` (``EcuConfig.systems[name]``; None: its
        default) into its application's configuration in ``app`` (``vh_ecu_config_t.app``)."""
        ...

    def scenario_dir(self) -> Path:
        """Where its shipped scenarios are (the demo runs every file there that it claims)."""
        ...

    def claims(self, doc: dict) -> bool:
        """Whether a parsed scenario file is one of its scenarios."""
        ...

    def load(self, path: Path) -> Any:
        """The validated scenario of a file it claims."""
        ...

    def car(self, scenario: Any, duration_s: float | None = None) -> Any:
        """A fresh car for the scenario, its whole duration unless `duration_s` is given: a
        :class:`~vehest_can.sim.car.Car`, for :func:`~vehest_can.sim.session.run_inprocess` and ``SimMaster``."""
        ...

    def setup(self, scenarios: list, out: Path) -> Setup:
        """Prepare the ECU for these scenarios of this system (e.g. device calibrations)."""
        ...

    def metrics(self, scenario: Any, session: Any, out_dir: Path, setup: Setup) -> dict:
        """Its figures of one session against the plant and the paper; writes its plots to out_dir."""
        ...

    def tables(self, metrics: list[dict]) -> list[str]:
        """The terminal tables of its sessions' metrics (none: an empty list)."""
        ...


class Registration:
    """What the systems' registrations have alike; a system subclasses it and names its own scenario
    folder, loader and car as ``scenario_dir = staticmethod(...)``, ``load``, ``car``. By default it
    claims the scenario files whose ``kind`` is one of its kinds and asks nothing of the ECU."""

    kinds: tuple[str, ...] = ()
    estimators: tuple[EcuEstimator, ...] = ()
    ecu_counters: tuple[EcuCounters, ...] = ()
    studies: tuple[Study, ...] = ()

    def claims(self, doc: dict) -> bool:
        return doc.get("kind") in self.kinds

    def configure_car(self, app: Any, car: Any) -> None:
        """(Optional.) Write a car (:class:`~vehest_can.carfile.CarFile`, :attr:`.ecu.EcuConfig.car`) into its
        application's vehicle model in ``app`` (``vh_ecu_config_t.app``), before ``configure_ecu``."""
        ...

    def configure_ecu(self, app: Any, part: Any) -> None:
        """By default its application keeps the C core's default configuration."""

    def setup(self, scenarios: list, out: Path) -> Setup:
        return Setup()


_extra: list[System] = []


def register(system: System) -> None:
    """Add a system that does not live in this package (tests, plug-ins)."""
    _extra.append(system)


def unregister(system: System) -> None:
    _extra.remove(system)


def registered() -> list[System]:
    """Every system: ``systems/<name>/system.py``'s ``SYSTEM`` by name, then those registered."""
    found = []
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if info.ispkg and importlib.util.find_spec(f"{__name__}.{info.name}.system") is not None:
            found.append(importlib.import_module(f"{__name__}.{info.name}.system").SYSTEM)
    return found + _extra


def fault_study(scenario_doc: dict | None = None) -> FaultStudy:
    """The fault study of the system a scenario belongs to (None: the first system that has one)."""
    studies = [(s, s.faults) for s in registered() if s.faults is not None]
    if scenario_doc is not None:
        studies = [(s, f) for s, f in studies if s.claims(scenario_doc)] or studies
    if not studies:
        raise LookupError("no registered system has a fault study")
    return studies[0][1]


def claiming(doc: dict, systems: list[System] | None = None) -> System | None:
    """The system whose scenario a parsed file is."""
    return next((s for s in (systems or registered()) if s.claims(doc)), None)


def unclaimed(doc: dict, systems: list[System] | None = None) -> str:
    """Why no system reads a parsed scenario file: ``kind: ...``, naming the kinds there are."""
    kinds = ", ".join(f'"{k}"' for s in (systems or registered()) for k in s.kinds)
    if not isinstance(doc, dict) or "kind" not in doc:
        return f"kind: missing: a scenario starts with its system's kind, one of {kinds}"
    return f"kind: no registered system reads kind = {doc['kind']!r} (the kinds: {kinds})"


def _dirs(systems: list[System]) -> list[Path]:
    return list(dict.fromkeys(s.scenario_dir() for s in systems))


def shipped_scenarios(systems: list[System] | None = None) -> list[Path]:
    """Every shipped scenario file some system claims, folder by folder, by name."""
    systems = registered() if systems is None else systems
    return [p for d in _dirs(systems) for p in sorted(d.glob("*.toml")) if claiming(read_toml(p), systems)]


def load_any_scenario(name_or_path: str | Path, systems: list[System] | None = None) -> tuple[System, Any]:
    """(system, scenario) of a file, or of a shipped scenario's name: the registered system that claims it."""
    systems = registered() if systems is None else systems
    path = Path(name_or_path)
    if not path.is_file() and path.suffix != ".toml" and len(path.parts) == 1:
        path = next((d / f"{path}.toml" for d in _dirs(systems) if (d / f"{path}.toml").is_file()), path)
    if not path.is_file():
        names = sorted(p.stem for d in _dirs(systems) for p in d.glob("*.toml"))
        raise ScenarioError(f"{path}: no such scenario file, nor a shipped scenario's name (shipped: {', '.join(names)})")
    doc = read_toml(path)
    system = claiming(doc, systems)
    if system is None:
        raise ScenarioError(f"{path}: {unclaimed(doc, systems)}")
    return system, system.load(path)
