"""The console script starts at once: `vehest-can --help` and a verb's `--help` load neither numpy nor
the C core, plotting, MF4 or Dask (their time is measured by `vehest-can bench`, not asserted here)."""
import subprocess
import sys

import pytest

HEAVY = ("numpy", "vehest_can._native", "matplotlib", "asammdf", "pandas", "dask", "cantools", "numba", "scipy")

PROBE = """
import sys
from vehest_can.cli import main
try:
    main(sys.argv[1:])
except SystemExit:
    pass
print("LOADED", " ".join(m for m in {heavy!r} if m in sys.modules))
"""


@pytest.mark.parametrize("argv", [["--help"], ["demo", "--help"], ["replay", "--help"], ["sim", "--help"],
                                  ["campaign", "--help"], ["characterise", "--help"]])
def test_help_loads_nothing_heavy(argv):
    out = subprocess.run([sys.executable, "-c", PROBE.format(heavy=HEAVY), *argv], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert "usage: vehest-can" in out.stdout
    loaded = out.stdout.rsplit("LOADED", 1)[1].split()
    assert loaded == [], f"{' '.join(argv)} loaded {loaded}"


def test_the_top_level_help_lists_every_verb():
    from vehest_can.cli import verbs

    out = subprocess.run([sys.executable, "-m", "vehest_can.cli", "--help"], capture_output=True, text=True, timeout=120)
    for verb in verbs():
        assert f"    {verb}" in out.stdout


def test_an_mf4_command_line_still_gets_mf4(tmp_path):
    """python-can is imported without asammdf only for command lines that name no MF4."""
    pytest.importorskip("asammdf")
    probe = ("import sys\nfrom vehest_can.cli import _defer_mf4\n_defer_mf4(sys.argv[1:])\n"
             "import can.io.mf4 as m\nprint('ASAMMDF', m.asammdf is not None)")
    for argv, want in ((["replay", "x.log"], "False"), (["replay", "x.mf4"], "True")):
        out = subprocess.run([sys.executable, "-c", probe, *argv], capture_output=True, text=True, timeout=120)
        assert out.stdout.split()[-1] == want, (argv, out.stdout, out.stderr)
