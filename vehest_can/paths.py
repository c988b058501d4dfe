"""Where the DBC files are: inside the installed package, or dbc/ of a source checkout."""
from __future__ import annotations

from pathlib import Path

_PKG_DBC = Path(__file__).resolve().parent / "dbc"
_SRC_DBC = Path(__file__).resolve().parent.parent / "dbc"


def dbc_dir() -> Path:
    return _PKG_DBC if any(_PKG_DBC.glob("*.dbc")) else _SRC_DBC


def dbc_path(bus: str = "pt") -> Path:
    return dbc_dir() / f"vehest_{bus}.dbc"
