"""The SecOC C under AddressSanitizer + UndefinedBehaviorSanitizer (float-cast-overflow included),
and its cffi declarations."""
import shutil
import subprocess
import sys
from pathlib import Path

import cffi
import pytest

ROOT = Path(__file__).resolve().parents[2]
SECOC = ROOT / "c_core" / "secoc"
sys.path.insert(0, str(ROOT / "c_core"))
from cbuild import STRICT_FLAGS, headers_cdef, libcrypto  # noqa: E402

SOURCES = [SECOC / "vh_cmac.c", SECOC / "vh_secoc.c", SECOC / "vh_aes128_host.c"]

pytestmark = pytest.mark.rebuild

SAN = ["-fsanitize=address,undefined,float-cast-overflow", "-fno-sanitize-recover=all",
       "-fno-omit-frame-pointer", "-g", "-O1"]


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_secoc_under_asan_ubsan_with_hostile_frames(tmp_path):
    exe = tmp_path / "sanitize_secoc"
    build = subprocess.run(["cc", *STRICT_FLAGS, *SAN, f"-I{SECOC}",
                            *[str(s) for s in SOURCES],
                            str(Path(__file__).with_name("c") / "sanitize_secoc.c"),
                            libcrypto(), "-o", str(exe)], capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    run = subprocess.run([str(exe), "100000"], capture_output=True, text=True, timeout=600,
                         env={"ASAN_OPTIONS": "detect_leaks=1", "UBSAN_OPTIONS": "print_stacktrace=1"})
    assert run.returncode == 0, run.stdout + run.stderr
    assert "sanitize_secoc: ok" in run.stdout and "passed at" not in run.stdout
    assert "runtime error" not in run.stderr
    print("\n" + run.stdout)


def test_cdef_is_the_headers_without_their_preprocessor_lines():
    text = headers_cdef([SECOC / "vh_aes128.h", SECOC / "vh_cmac.h", SECOC / "vh_secoc.h"])
    cffi.FFI().cdef(text)
    assert "#include" not in text and "#define VH_SECOC_TAIL_BYTES 4" in text


def test_no_heap_and_no_aes_of_our_own():
    """The SecOC C allocates nothing, and AES is the backend's, not code of ours."""
    for src in SOURCES:
        text = src.read_text()
        for banned in ("malloc", "calloc", "realloc", "free("):
            assert banned not in text, (src.name, banned)
    cmac_c = (SECOC / "vh_cmac.c").read_text()
    assert "sbox" not in cmac_c.lower() and "0x63" not in cmac_c  # no S-box: the mode only


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_bench_runs_and_counts_its_verdicts(tmp_path):
    """c_core/bench/bench_secoc.c: figures are measured, not asserted; here it only has to run and
    see every genuine frame accepted and every forged/replayed one rejected (it checks that itself)."""
    exe = tmp_path / "bench_secoc"
    bench = ROOT / "c_core" / "bench"
    build = subprocess.run(["cc", *STRICT_FLAGS, "-O2", f"-I{SECOC}", f"-I{bench}",
                            *[str(s) for s in SOURCES], str(bench / "bench_secoc.c"),
                            libcrypto(), "-o", str(exe)], capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    run = subprocess.run([str(exe), "20"], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stdout
    names = [line.split()[0] for line in run.stdout.splitlines()]
    assert names == ["clock", "aes_block", "cmac_38", "protect_28", "verify_28", "verify_forged"]
