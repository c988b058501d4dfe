"""The slave under AddressSanitizer + UndefinedBehaviorSanitizer, and its cffi declarations."""
import shutil
import subprocess
import sys
from pathlib import Path

import cffi
import pytest

ROOT = Path(__file__).resolve().parents[2]
XCP = ROOT / "c_core" / "xcp"
SECOC = ROOT / "c_core" / "secoc"
sys.path.insert(0, str(ROOT / "c_core"))
from cbuild import STRICT_FLAGS, compile_strict, headers_cdef, libcrypto  # noqa: E402

pytestmark = pytest.mark.rebuild

#: the slave with the CMAC it keys seed & key with (c_core/secoc), AES from libcrypto
SOURCES = [XCP / "vh_xcp.c", SECOC / "vh_cmac.c", SECOC / "vh_aes128_host.c"]
SLAVE = [f"-I{XCP}", f"-I{SECOC}", *map(str, SOURCES)]

SAN = ["-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer", "-g", "-O1"]


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_slave_under_asan_ubsan_with_random_cros(tmp_path):
    exe = tmp_path / "sanitize_xcp"
    build = subprocess.run(["cc", *STRICT_FLAGS, *SAN, *SLAVE,
                            str(Path(__file__).with_name("c") / "sanitize_xcp.c"), "-lm", libcrypto(), "-o", str(exe)],
                           capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    run = subprocess.run([str(exe), "200000"], capture_output=True, text=True, timeout=600,
                         env={"ASAN_OPTIONS": "detect_leaks=1:abort_on_error=0", "UBSAN_OPTIONS": "print_stacktrace=1"})
    assert run.returncode == 0, run.stdout + run.stderr
    assert "sanitize_xcp: ok" in run.stdout and "runtime error" not in run.stderr
    print("\n" + run.stdout)


def test_cdef_is_the_header_without_its_preprocessor_lines():
    text = headers_cdef([SECOC / "vh_aes128.h", SECOC / "vh_cmac.h", XCP / "vh_xcp.h"])
    ffi = cffi.FFI()
    ffi.cdef(text)  # raises on anything cffi cannot parse
    assert "#include" not in text and "#ifndef" not in text
    assert "#define VH_XCP_MAX_ODT 64" in text
    for fn in ("vh_xcp_init", "vh_xcp_reset", "vh_xcp_tick", "vh_xcp_rx", "vh_xcp_event", "vh_xcp_tx_pop"):
        assert fn in text


def test_slave_includes_only_the_c_library_headers():
    allowed = {"<stdint.h>", "<stddef.h>", "<stdbool.h>", "<string.h>", '"vh_xcp.h"', '"vh_cmac.h"'}
    for f in (XCP / "vh_xcp.h", XCP / "vh_xcp.c"):
        incs = {line.split()[1] for line in f.read_text().splitlines() if line.startswith("#include")}
        assert incs <= allowed, (f.name, incs - allowed)


def test_slave_compiles_with_the_strict_flags(tmp_path):
    objs = compile_strict(SOURCES, [XCP, SECOC], tmp_path)
    assert all(Path(o).exists() for o in objs)


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_bench_runs_on_a_tiny_size(tmp_path):
    """c_core/bench/bench_xcp.c: the figures are measured, not asserted; here it only has to run."""
    exe = tmp_path / "bench_xcp"
    build = subprocess.run(["cc", *STRICT_FLAGS, "-O2", *SLAVE, str(XCP.parent / "bench" / "bench_xcp.c"),
                            libcrypto(), "-o", str(exe)], capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    run = subprocess.run([str(exe), "2000"], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stdout
    names = [line.split()[0] for line in run.stdout.splitlines()]
    assert names == ["clock", "idle", "daq20_classic", "daq20_fd", "short_upload", "download"]
