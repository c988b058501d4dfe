"""The wheel in a clean venv (#13 point 1): built from this tree, installed without extras (the
runtime dependencies from the wheelhouse `make install` downloads: the suite runs offline), then
`vehest-can --help`, `vehest-can examples` and a short demo, run outside the checkout."""
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[2]
WHEELHOUSE = ROOT / "build" / "wheelhouse"

pytestmark = [pytest.mark.slow, pytest.mark.multicast, pytest.mark.rebuild]


def run(cmd, **kw):
    return subprocess.run(cmd, capture_output=True, text=True, timeout=1200, **kw)


@pytest.mark.skipif(not any(WHEELHOUSE.glob("numpy-*.whl")), reason="no wheelhouse: `make install` downloads it")
def test_the_wheel_installs_and_runs_in_a_clean_venv(tmp_path):
    dist = tmp_path / "dist"
    built = run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(dist), str(ROOT)])
    assert built.returncode == 0, built.stderr[-3000:]
    (wheel,) = dist.glob("vehest_can-*.whl")
    assert wheel.name.endswith("-cp311-abi3-linux_x86_64.whl"), wheel.name
    names = zipfile.ZipFile(wheel).namelist()
    for shipped in ("vehest_can/dbc/vehest_pt.dbc", "vehest_can/scenarios/driveline/launch_2nd.toml",
                    "vehest_can/examples/hil/loopback.toml", "vehest_can/examples/systemd/vehest-ecu.service"):
        assert shipped in names
    assert any(n.startswith("vehest_can/_native") and n.endswith(".abi3.so") for n in names)

    venv = tmp_path / "venv"
    assert run([sys.executable, "-m", "venv", str(venv)]).returncode == 0
    pip = run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", "--no-index", "--find-links", str(WHEELHOUSE),
               str(wheel)])
    assert pip.returncode == 0, pip.stderr[-3000:]
    assert run([str(venv / "bin" / "python"), "-c", "import scipy"]).returncode != 0  # no test extra

    exe = str(venv / "bin" / "vehest-can")
    work = tmp_path / "elsewhere"
    work.mkdir()
    helped = run([exe, "--help"], cwd=work)
    assert helped.returncode == 0 and "replay" in helped.stdout and "monitor" in helped.stdout, helped.stderr
    listed = run([exe, "examples"], cwd=work)
    assert listed.returncode == 0 and "hil/loopback.toml" in listed.stdout
    assert str(venv) in listed.stdout  # from the installed package, not the checkout
    (work / "short.toml").write_text('kind = "driveline"\nname = "short"\ndescription = "0.5 s"\nduration_s = 0.5\nseed = 3\n'
                                     '[driver]\ngear = 2\nthrottle = [[0.0, 0.3], [0.5, 0.5]]\n')
    demo = run([exe, "demo", "short.toml", "-o", "out"], cwd=work)
    assert demo.returncode == 0, demo.stdout[-2000:] + demo.stderr[-2000:]
    assert "bus lockstep == in-process lockstep: identical" in demo.stdout
    assert (work / "out" / "short" / "session.log").stat().st_size > 1000
