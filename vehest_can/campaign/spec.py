"""Campaign files: a base scenario, the parameters to vary and how, runs, seed, acceptance lines.

    [campaign]
    name = "tireforce_payload"
    base = "chassis_relation_70kph"      # a shipped scenario's name, or a path (any system's kind)
    runs = 50
    seed = 2026
    metrics = ["variants.skfmec-fixed.rms_pct.*"]   # which metrics to keep (glob on dotted names)

    [[vary]]
    key = "vehicle.mass_delta_kg"        # a dotted path into the scenario document (list items: road.mu[0][1]),
                                         # or "fault": faults in the `faults` verb's syntax, "" for none
    dist = "uniform"                     # uniform (low, high) | normal (mean, sd) | list (values) | grid (values)
    low = -100
    high = 400

    [[acceptance]]
    metric = "variants.skfmec-fixed.rms_pct.FL"
    max = 7.0                            # and/or min

Run ``i`` draws its values from its own generator, seeded from (campaign seed, i), and its
scenario's ``seed`` is derived the same way (unless a vary line sets it), so a run's result does
not depend on which worker ran it or on how many there were. ``grid`` lines form the cartesian
product (their ``runs`` is the product's size; random lines are drawn on top of each grid point).
"""
from __future__ import annotations

import copy
import fnmatch
import itertools
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError, ScenarioError
from ..paths import ShippedSet
from ..schema import Checker, read_toml

#: the shipped campaigns: inside the installed package, or firmware_sim/campaigns/ of a checkout
CAMPAIGNS = ShippedSet("campaigns", "firmware_sim/campaigns")

FAULT = "fault"  # a vary key that is not a scenario key: fault specs, ";"-separated
CAR = "car"  # the scenario key of the 14-DOF car's car file: its values resolved against the campaign file
DISTS = {"uniform": ("low", "high"), "normal": ("mean", "sd"), "list": ("values",), "grid": ("values",)}


@dataclass(frozen=True)
class Vary:
    key: str
    dist: str
    args: tuple


@dataclass(frozen=True)
class Acceptance:
    metric: str
    lo: float | None
    hi: float | None

    @property
    def line(self) -> str:
        parts = ([f">= {self.lo:g}"] if self.lo is not None else []) + ([f"<= {self.hi:g}"] if self.hi is not None else [])
        return f"{self.metric} {' and '.join(parts)}"

    def passes(self, value: float) -> bool:
        return (math.isfinite(value) and (self.lo is None or value >= self.lo)
                and (self.hi is None or value <= self.hi))


@dataclass(frozen=True)
class Campaign:
    path: Path
    name: str
    base_path: Path
    base: dict               # the base scenario's TOML document
    runs: int
    seed: int
    vary: tuple[Vary, ...]
    metrics: tuple[str, ...]  # globs on the dotted metric names; empty = all
    acceptance: tuple[Acceptance, ...] = field(default=())

    def grid(self) -> list[tuple]:
        axes = [v.args[0] for v in self.vary if v.dist == "grid"]
        return list(itertools.product(*axes)) if axes else [()]

    def run_doc(self, index: int) -> tuple[dict, dict]:
        """Run ``index``'s scenario document and the values it drew (by dotted key)."""
        if not 0 <= index < self.runs:
            raise IndexError(index)
        rng = np.random.default_rng([self.seed, index])
        grid = self.grid()[index % len(self.grid())]
        values, g = {}, iter(grid)
        for v in self.vary:
            if v.dist == "grid":
                values[v.key] = next(g)
            elif v.dist == "list":
                values[v.key] = v.args[0][int(rng.integers(len(v.args[0])))]
            elif v.dist == "uniform":
                values[v.key] = float(rng.uniform(*v.args))
            else:
                values[v.key] = float(rng.normal(*v.args))
        doc = copy.deepcopy(self.base)
        doc["seed"] = int(np.random.default_rng([self.seed, index, 1]).integers(1, 2**63))
        doc["name"] = f"{self.name}_run{index:05d}"
        for key, value in values.items():
            if key != FAULT:
                set_dotted(doc, key, value)
        return doc, values

    def faults(self, values: dict) -> tuple[str, ...] | None:
        """The run's faults (None: the campaign varies none, the plain in-process run)."""
        if not any(v.key == FAULT for v in self.vary):
            return None
        return tuple(f for f in str(values.get(FAULT, "")).split(";") if f.strip())

    def keep(self, metric: str) -> bool:
        return not self.metrics or any(fnmatch.fnmatchcase(metric, g) for g in self.metrics)


_STEP = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)$")


def set_dotted(doc: dict, key: str, value) -> None:
    """Set ``key`` (``vehicle.mass_delta_kg``; list items by index: ``road.mu[0][1]``) in ``doc``;
    tables on the way are made, list items must exist in the base scenario."""
    steps: list = []
    for part in key.split("."):
        m = _STEP.match(part)
        if not m:
            raise ScenarioError(f"{key}: {part!r} is not a key (letters, digits, _; [i] for a list item)")
        steps.append(m[1])
        steps += [int(i) for i in re.findall(r"\[(\d+)\]", m[2])]
    node = doc
    for i, step in enumerate(steps[:-1]):
        nxt = steps[i + 1]
        if isinstance(step, int):
            if not isinstance(node, list) or step >= len(node):
                raise ScenarioError(f"{key}: the base scenario has no item [{step}] there")
            node = node[step]
        else:
            if not isinstance(node, dict):
                raise ScenarioError(f"{key}: {step} is not inside a table in the base scenario")
            node = node.setdefault(step, [] if isinstance(nxt, int) else {})
    last = steps[-1]
    if isinstance(last, int):
        if not isinstance(node, list) or last >= len(node):
            raise ScenarioError(f"{key}: the base scenario has no item [{last}] there")
        node[last] = value
    elif not isinstance(node, dict):
        raise ScenarioError(f"{key}: {last} is not inside a table in the base scenario")
    else:
        node[last] = value


def _number(chk: Checker, value, key, *, integer=False, lo=-math.inf, hi=math.inf):
    ok = not isinstance(value, bool) and isinstance(value, int if integer else (int, float))
    if not ok or not math.isfinite(value) or not lo <= value <= hi:
        what = "an integer" if integer else "a finite number"
        chk.fail(key, f"must be {what} in [{lo:g}, {hi:g}], not {value!r}")
    return value


def load_campaign(path: str | Path) -> Campaign:
    from .systems import resolve_base

    path = Path(path)
    chk = Checker(path)
    doc = chk.table(read_toml(path), "", {"campaign", "vary", "acceptance"})
    top: Any = doc.get("campaign")
    if not isinstance(top, dict):
        chk.fail("campaign", "missing: a campaign file starts with a [campaign] table")
    chk.table(top, "campaign", {"name", "base", "runs", "seed", "metrics"})
    for k in ("base", "runs"):
        if k not in top:
            chk.fail(f"campaign.{k}", "missing (required)")
    if not isinstance(top["base"], str):
        chk.fail("campaign.base", f"must be a scenario name or path, not {top['base']!r}")
    base_path, base = resolve_base(top["base"], path.parent)
    vary = []
    lines = doc.get("vary", [])
    if not isinstance(lines, list):
        chk.fail("vary", "must be an array of tables ([[vary]])")
    for i, v in enumerate(lines):
        k = f"vary[{i}]"
        if not isinstance(v, dict):
            chk.fail(k, "must be a table")
        dist = v.get("dist")
        if dist not in DISTS:
            chk.fail(f"{k}.dist", f"must be one of {', '.join(DISTS)}, not {dist!r}")
        if not isinstance(v.get("key"), str) or not v["key"]:
            chk.fail(f"{k}.key", "missing: the dotted path of a scenario key (e.g. vehicle.mass_delta_kg)")
        extra = set(v) - {"key", "dist", *DISTS[dist]}
        if extra:
            chk.fail(f"{k}.{sorted(extra)[0]}", f"unknown key for dist = {dist!r} (expected {', '.join(DISTS[dist])})")
        for a in DISTS[dist]:
            if a not in v:
                chk.fail(f"{k}.{a}", f"missing (dist = {dist!r} needs {', '.join(DISTS[dist])})")
        args: tuple
        if dist in ("list", "grid"):
            if not isinstance(v["values"], list) or not v["values"]:
                chk.fail(f"{k}.values", "must be a non-empty list")
            args = (tuple(v["values"]),)
        else:
            args = tuple(float(_number(chk, v[a], f"{k}.{a}")) for a in DISTS[dist])
            if dist == "uniform" and not args[0] < args[1]:
                chk.fail(f"{k}.high", f"must be above low ({args[0]:g}), not {args[1]:g}")
            if dist == "normal" and args[1] < 0:
                chk.fail(f"{k}.sd", f"must be >= 0, not {args[1]:g}")
        vary.append(Vary(v["key"], dist, args))
    for i, v in enumerate(vary):
        if v.key == FAULT:
            if v.dist not in ("list", "grid"):
                chk.fail(f"vary[{i}].dist", f'the {FAULT} key takes list or grid (of fault strings)')
            from ..faults.spec import parse_fault

            for j, text in enumerate(v.args[0]):
                if not isinstance(text, str):
                    chk.fail(f"vary[{i}].values[{j}]", f"must be a fault string (\"\" for none), not {text!r}")
                for f in (f for f in text.split(";") if f.strip()):
                    try:
                        parse_fault(f)
                    except ConfigError as exc:  # the faults module's own clear message
                        chk.fail(f"vary[{i}].values[{j}]", str(exc))
        if v.key == CAR:  # a car axis: names, or paths relative to this file (the runs' documents are the base's)
            if v.dist not in ("list", "grid"):
                chk.fail(f"vary[{i}].dist", f"the {CAR} key takes list or grid (of car names or files)")
            from ..carfile import car_spec, load_car

            specs = []
            for j, text in enumerate(v.args[0]):
                if not isinstance(text, str):
                    chk.fail(f"vary[{i}].values[{j}]", f"must be a car file or a shipped car's name, not {text!r}")
                try:
                    specs.append(car_spec(load_car(text, relative_to=path.parent)))
                except ConfigError as exc:
                    chk.fail(f"vary[{i}].values[{j}]", str(exc))
            vary[i] = Vary(v.key, v.dist, (tuple(specs),))
    keys = [v.key for v in vary]
    if len(set(keys)) != len(keys):
        chk.fail("vary", f"key {next(k for k in keys if keys.count(k) > 1)!r} is varied twice")
    n_grid = math.prod(len(v.args[0]) for v in vary if v.dist == "grid")
    runs = _number(chk, top["runs"], "campaign.runs", integer=True, lo=1, hi=10**7)
    if runs % n_grid:
        chk.fail("campaign.runs", f"{runs} is not a multiple of the grid's {n_grid} points")
    seed = _number(chk, top.get("seed", 0), "campaign.seed", integer=True, lo=0, hi=2**63 - 1)
    metrics = top.get("metrics", [])
    if not isinstance(metrics, list) or not all(isinstance(m, str) for m in metrics):
        chk.fail("campaign.metrics", "must be a list of metric names (globs allowed)")
    acc = []
    for i, a in enumerate(doc.get("acceptance", [])):
        k = f"acceptance[{i}]"
        if not isinstance(a, dict) or not isinstance(a.get("metric"), str):
            chk.fail(f"{k}.metric", "missing: the dotted name of a metric")
        chk.table(a, k, {"metric", "min", "max"})
        if "min" not in a and "max" not in a:
            chk.fail(k, "needs min, max or both")
        lo = float(_number(chk, a["min"], f"{k}.min")) if "min" in a else None
        hi = float(_number(chk, a["max"], f"{k}.max")) if "max" in a else None
        acc.append(Acceptance(a["metric"], lo, hi))
    name = top.get("name", path.stem)
    if not isinstance(name, str) or not name:
        chk.fail("campaign.name", "must be a non-empty string")
    c = Campaign(path, name, base_path, base, int(runs), int(seed), tuple(vary), tuple(metrics), tuple(acc))
    # every dotted key lands where the system's own loader accepts it: check run 0 now, not at run 37
    from .systems import system_for, takes_faults, validate

    system = system_for(base)
    if FAULT in keys and not takes_faults(system):
        chk.fail(f"vary[{keys.index(FAULT)}].key", f"the {system.name} system's runs take no faults (it has no fault study)")
    try:
        validate(system, c.run_doc(0)[0], base_path)
    except ScenarioError as exc:
        raise ScenarioError(f"{path}: run 0 of this campaign is not a valid scenario: {exc}") from None
    return c
