"""Where shipped data is: inside the installed package (setup.py copies it there), or in the
source checkout. One rule for the DBC files and the scenarios."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

_PKG = Path(__file__).resolve().parent
_SRC = _PKG.parent


def shipped_dir(package_dir: str, checkout_dir: str, pattern: str) -> Path:
    """`vehest_can/<package_dir>` when it holds files matching `pattern`, else `<checkout_dir>`."""
    installed = _PKG / package_dir
    return installed if any(installed.glob(pattern)) else _SRC / checkout_dir


def shipped_file(name_or_path: str | Path, directory: Path, suffix: str = ".toml") -> Path:
    """An existing path as given, else the name of a file shipped in `directory`."""
    p = Path(name_or_path)
    if p.suffix == suffix or p.exists() or len(p.parts) > 1:
        return p
    return directory / f"{p.name}{suffix}"


@dataclass(frozen=True)
class ShippedSet:
    """A folder of shipped TOML files (a system's scenarios, the campaigns)."""

    package_dir: str
    checkout_dir: str

    def dir(self) -> Path:
        return shipped_dir(self.package_dir, self.checkout_dir, "*.toml")

    def names(self) -> list[str]:
        """The files' stems, sorted."""
        return sorted(p.stem for p in self.dir().glob("*.toml"))

    def path(self, name_or_path: str | Path) -> Path:
        """An existing path as given, else a shipped file's name."""
        return shipped_file(name_or_path, self.dir())


def examples_dir() -> Path:
    """The shipped examples: HIL bench configurations (hil/), the systemd unit (systemd/)."""
    return shipped_dir("examples", "examples", "*/*")


def dbc_dir() -> Path:
    return shipped_dir("dbc", "dbc", "*.dbc")


def dbc_path(bus: str = "pt") -> Path:
    return dbc_dir() / f"vehest_{bus}.dbc"
