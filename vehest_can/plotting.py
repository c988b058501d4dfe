"""Figures of the reports: matplotlib without a display (reports run on CI, under systemd, over
ssh), and one way of saving them."""
from __future__ import annotations

from pathlib import Path
from typing import Any


def pyplot() -> Any:
    """matplotlib.pyplot on the Agg backend (imported late: the CLI starts without matplotlib)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


class Figures:
    """The figures a report writes into one folder, in the order written."""

    def __init__(self, out_dir: Path, dpi: int = 110):
        self.out_dir = Path(out_dir)
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.dpi = dpi
        self.paths: list[Path] = []

    def save(self, fig, name: str) -> Path:
        """Lay out, write ``out_dir/name`` and close ``fig``."""
        fig.tight_layout()
        self.paths.append(self.out_dir / name)
        fig.savefig(self.paths[-1], dpi=self.dpi)
        pyplot().close(fig)
        return self.paths[-1]
