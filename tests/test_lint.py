"""The linter and the type checker are part of the suite: `ruff check` (config in pyproject.toml) on the
package and the tests, `mypy` on the package."""
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", *args], cwd=ROOT, capture_output=True, text=True, timeout=600)


def test_ruff():
    r = _run("ruff", "check", "--no-cache", "vehest_can", "tests")
    assert r.returncode == 0, r.stdout + r.stderr


def test_mypy():
    r = _run("mypy", "--cache-dir", str(ROOT / "build" / "mypy_cache"))   # files and options: pyproject.toml
    assert r.returncode == 0, r.stdout + r.stderr
