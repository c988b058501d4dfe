"""The C core built with AddressSanitizer + UndefinedBehaviorSanitizer and driven hard."""
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "c_core"))
import vehest_build  # noqa: E402

pytestmark = pytest.mark.rebuild

SAN = ["-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer", "-g", "-O1"]


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_firmware_under_asan_ubsan(tmp_path):
    gen = tmp_path / "generated"
    sources = [str(s) for s in vehest_build.firmware_sources(gen)]
    sources.append(str(ROOT / "tests" / "c" / "sanitize_main.c"))
    sim_driver = ROOT / "tests" / "c" / "sanitize_sim.c"
    defines = []
    if sim_driver.exists():
        sources.append(str(sim_driver))
        defines.append("-DVH_WITH_SIM")
    includes = [f"-I{d}" for d in vehest_build.sim_include_dirs(gen)]
    exe = tmp_path / "sanitize"
    build = subprocess.run(
        ["cc", *vehest_build.STRICT_FLAGS, *SAN, *defines, *includes, *sources, *vehest_build.LINK_FLAGS, "-o", str(exe)],
        capture_output=True, text=True,
    )
    assert build.returncode == 0, build.stderr
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=600,
                         env={"ASAN_OPTIONS": "detect_leaks=1:abort_on_error=0", "UBSAN_OPTIONS": "print_stacktrace=1"})
    assert run.returncode == 0, run.stdout + run.stderr
    assert "sanitize: ok" in run.stdout
    assert "runtime error" not in run.stderr
