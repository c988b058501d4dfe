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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Protocol


@dataclass
class Setup:
    """What a system asks of the ECU before its scenarios run: extra ``vehest-can daemon`` arguments
    for the ECU process and the same configuration applied to a local :class:`~.ecu.Ecu`."""

    daemon_args: list[str] = field(default_factory=list)
    configure: Callable[[Any], None] = lambda ecu: None


class System(Protocol):
    #: the one name: folder, docs page, tests folder, plot folder
    name: str
    #: scenario ``kind`` values it reads; the first is its own, the rest old names kept as aliases
    kinds: tuple[str, ...]
    #: its car runs on the wall clock (``demo --realtime``)
    realtime: bool

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
        """A fresh car for the scenario (its whole duration unless `duration_s` is given) (a :class:`~vehest_can.sim.session.Drive` or any object with
        the car interface), for :func:`~vehest_can.sim.session.run_inprocess` and ``SimMaster``."""
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


def claiming(doc: dict, systems: list[System] | None = None) -> System | None:
    """The system whose scenario a parsed file is."""
    return next((s for s in (systems or registered()) if s.claims(doc)), None)
