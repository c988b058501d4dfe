"""The one schema reader of every user file kind (scenarios of each system, HIL configurations, fault
files): TOML read once, each value checked, every error ``FILE: dotted.key: problem``.

A :class:`Checker` raises the error class of the file's kind (:class:`~vehest_can.errors.ScenarioError`
for scenarios, :class:`~vehest_can.errors.ConfigError` for configuration); :class:`Num` says which
numbers a key takes."""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

from .errors import ScenarioError, VehestError


@dataclass(frozen=True)
class Num:
    """A number in [lo, hi] (lo excluded when lo_open); integer=True accepts only integers."""

    lo: float
    hi: float
    integer: bool = False
    lo_open: bool = False

    def describe(self) -> str:
        kind = "an integer" if self.integer else "a number"
        left = "(" if self.lo_open else "["
        return f"{kind} in {left}{self.lo:g}, {self.hi:g}]"


class Checker:
    """Validates values and raises `error` naming the file and the dotted key."""

    def __init__(self, path: Path | str, error: type[VehestError] = ScenarioError):
        self.path = path
        self.error = error

    def fail(self, key: str, problem: str) -> NoReturn:
        raise self.error(f"{self.path}: {key}: {problem}")

    def table(self, value, key: str, allowed) -> dict:
        if not isinstance(value, dict):
            self.fail(key, f"must be a table ([{key}]), not {type_name(value)}")
        for k in value:
            if k not in allowed:
                self.fail(join(key, k), f"unknown key (expected one of: {', '.join(sorted(allowed))})")
        return value

    def boolean(self, value, key: str) -> bool:
        if not isinstance(value, bool):
            self.fail(key, f"must be true or false, not {type_name(value)}")
        return value

    def string(self, value, key: str) -> str:
        if not isinstance(value, str):
            self.fail(key, f"must be a string, not {type_name(value)}")
        return value

    def number(self, value, key: str, spec: Num):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or (
                spec.integer and not isinstance(value, int)):
            self.fail(key, f"must be {spec.describe()}, not {type_name(value)}")
        if not math.isfinite(value):
            self.fail(key, f"must be {spec.describe()}, not {value}")
        below = value <= spec.lo if spec.lo_open else value < spec.lo
        if below or value > spec.hi:
            self.fail(key, f"{value!r} is out of range: must be {spec.describe()}")
        return int(value) if spec.integer else float(value)

    def profile(self, value, key: str, spec: Num | tuple[str, ...],
                columns: tuple[str, ...] = ("value",)) -> tuple[tuple[Any, ...], ...]:
        """``[[time_s, v, ...], ...]`` with times strictly increasing: each v a number of ``spec``,
        or one of the words in ``spec``; ``columns`` names the values in messages."""
        shape = f"[time_s, {', '.join(columns)}]"
        if not isinstance(value, list) or not value:
            self.fail(key, f"must be a non-empty list of {shape} points")
        points: list[tuple[Any, ...]] = []
        for i, pt in enumerate(value):
            k = f"{key}[{i}]"
            if not isinstance(pt, list) or len(pt) != 1 + len(columns):
                self.fail(k, f"must be a {shape} point ({1 + len(columns)} values), not {pt!r}")
            t = self.number(pt[0], f"{k}[0]", Num(0.0, 1e6))
            if points and not t > points[-1][0]:
                self.fail(k, f"time {t:g} s does not come after the previous point's "
                             f"{points[-1][0]:g} s: times must increase strictly")
            points.append((t, *(self._point_value(v, f"{k}[{j + 1}]", spec) for j, v in enumerate(pt[1:]))))
        return tuple(points)

    def _point_value(self, value, key: str, spec: Num | tuple[str, ...]):
        if isinstance(spec, Num):
            return self.number(value, key, spec)
        word = self.string(value, key)
        if word not in spec:
            self.fail(key, f"must be {' or '.join(repr(w) for w in spec)}, not {word!r}")
        return word


def join(prefix: str, key: str) -> str:
    return f"{prefix}.{key}" if prefix else key


def type_name(value) -> str:
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string", list: "a list",
            dict: "a table"}.get(type(value), type(value).__name__)


def read_toml(path: Path, error: type[VehestError] = ScenarioError) -> dict:
    """A file's TOML document; `error` naming the file when it cannot be had."""
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{path}: (TOML syntax): {exc}") from None
    except UnicodeDecodeError as exc:  # TOML is UTF-8
        raise error(f"{path}: not UTF-8 text: {exc}") from None
    except OSError as exc:
        raise error(f"{path}: cannot read: {exc.strerror or exc}") from None
