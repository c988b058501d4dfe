"""c_core/roll built with the strict flags and AddressSanitizer + UndefinedBehaviorSanitizer,
driven hard from C (random inputs, NaN/Inf, indefinite and NaN covariances) in both precisions."""
import shutil
import subprocess
from pathlib import Path

import pytest

pytestmark = pytest.mark.rebuild

ROOT = Path(__file__).resolve().parents[2]
ROLL = ROOT / "c_core" / "roll"
COMMON = ROOT / "c_core" / "common"
STRICT = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-Wdouble-promotion"]
SAN = ["-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer", "-g", "-O1"]


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_roll_under_asan_ubsan(tmp_path):
    exe = tmp_path / "sanitize_roll"
    srcs = [ROLL / "vh_roll_f32.c", ROLL / "vh_roll_f64_host.c", ROLL / "vh_roll_params.c", COMMON / "vh_mathf.c",
            Path(__file__).parent / "c" / "sanitize_roll.c"]
    build = subprocess.run(["cc", *STRICT, *SAN, f"-I{ROLL}", f"-I{COMMON}", *map(str, srcs), "-lm", "-o", str(exe)],
                           capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=300,
                         env={"ASAN_OPTIONS": "detect_leaks=1", "UBSAN_OPTIONS": "print_stacktrace=1"})
    print(run.stdout)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "sanitize roll: ok" in run.stdout and "runtime error" not in run.stderr
