"""Boundaries of the C core that the build and these tests hold (issue 10, items 4 and 6).

* The DBC is the one source of every scale factor: each field of a generated message struct that
  carries a scaled signal is written through the generated ``_encode_round`` of that very signal
  and read through its ``_decode`` (or compared with its SNA value), in the firmware, the
  simulated nodes and the benches; no hand-made "floor(v / 0.02 + 0.5)" encoder or SCALE table.
* Firmware sources cannot include simulator headers: they compile with the firmware include path
  only (shown here by a firmware file that tries), every firmware folder is scanned.
* ``c_core/bench`` reaches ``firmware_sim`` only through the declared bench include path.
"""
import re
import shutil
import subprocess
import sys
from pathlib import Path

import cantools
import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "c_core"))
import dbcgen  # noqa: E402
import vehest_build  # noqa: E402

SIM_HEADERS = sorted(p.name for p in vehest_build.SIM_INCLUDE_DIR.glob("*.h"))
HAND_ENCODER = re.compile(r"floor\([^;]*?[/*]\s*(\d+\.\d*|\d*\.\d+|\d+[eE]-?\d+)\s*\+\s*0\.5\)")


def _strip(code: str) -> str:
    return re.sub(r"//[^\n]*", "", re.sub(r"/\*.*?\*/", "", code, flags=re.S))


def c_sources() -> list[Path]:
    """Every hand-written C file that packs or unpacks frames: firmware, simulator, benches."""
    files = [p for d in vehest_build.FIRMWARE_DIRS for p in sorted(d.glob("*.[ch]"))]
    files += sorted((ROOT / "firmware_sim" / "src").glob("*.c")) + sorted((ROOT / "c_core" / "bench").glob("*.c"))
    return files


def scaled_signals() -> dict[str, tuple[str, set[str]]]:
    """struct name of each generated message -> (its C prefix, its scaled signals in snake case)."""
    out = {}
    for dbc in sorted((ROOT / "dbc").glob("vehest_*.dbc")):
        name = dbcgen.db_name(dbc)
        for m in cantools.database.load_file(str(dbc)).messages:
            prefix = f"{name}_{dbcgen.camel_to_snake_case(m.name)}"
            sigs = {dbcgen.camel_to_snake_case(s.name) for s in m.signals if s.scale != 1 or s.offset != 0}
            out[f"{prefix}_t"] = (prefix, sigs)
    return out


@pytest.fixture(scope="module")
def preprocessed(tmp_path_factory):
    if shutil.which("cc") is None:
        pytest.skip("no C compiler")
    gen = tmp_path_factory.mktemp("gen")
    dbcgen.generate_all(gen)
    inc = [f"-I{d}" for d in vehest_build.sim_include_dirs(gen)]
    out = {}
    for src in c_sources():
        if src.suffix == ".c":
            r = subprocess.run(["cc", "-E", "-P", "-std=c99", *inc, str(src)], capture_output=True, text=True, check=True)
            out[src] = r.stdout
    return out


def test_no_hand_written_encoder_or_scale_table():
    for src in c_sources():
        code = _strip(src.read_text())
        assert not HAND_ENCODER.search(code), f"{src}: a hand-written encoder; use the generated _encode_round"
        assert not re.search(r"#define\s+\w*SCALE\w*\s+[\d.]", code), f"{src}: a scale #define"
        assert not re.search(r"\bSCALE\s*\[", code), f"{src}: a scale table"


def test_every_scaled_signal_goes_through_the_generated_codec(preprocessed):
    msgs = scaled_signals()
    checked = 0
    for src, code in preprocessed.items():
        text = _strip(src.read_text())
        for struct, var in re.findall(r"struct (vh_\w+_t) (\w+);", text):
            if struct not in msgs:
                continue
            prefix, sigs = msgs[struct]
            for sig in sigs:
                for m in re.finditer(rf"\b{var}\.{sig}\b(\s*=(?!=)([^;]*);)?", code):
                    before = code[max(0, m.start() - len(prefix) - len(sig) - 14):m.start()]
                    after = code[m.end():m.end() + 4]
                    if m.group(1):  # a write
                        rhs = m.group(2)
                        assert (f"{prefix}_{sig}_encode_round(" in rhs or f"{prefix}_{sig}_encode_q(" in rhs
                                or f"{prefix}_{sig}_encode_qs(" in rhs
                                or re.fullmatch(r"\s*\(?-?\d+u?\)?\s*", rhs)), \
                            f"{src.name}: {var}.{sig} = {rhs.strip()[:60]} (not the DBC's encoder)"
                    else:  # a read: the generated decode, or a comparison with a raw constant (SNA)
                        assert (before.endswith(f"{prefix}_{sig}_decode(") or before.endswith(f"{prefix}_{sig}_decode_q(")
                                or re.match(r"\s*[!=]=", after)), \
                            f"{src.name}: {var}.{sig} read by hand"
                    checked += 1
    assert checked >= 80  # every encode and decode of the ECU and both sensor nodes


def test_the_check_catches_a_hand_written_scale():
    assert HAND_ENCODER.search("r = floor(v / 0.02 + 0.5);")
    assert HAND_ENCODER.search("est.x = (int16_t)floor(f->x[2] * 4.0 + 0.5);")
    assert not HAND_ENCODER.search("mm = floor(ldexp(fr, 31) + 0.5);")


def test_firmware_folders_include_no_simulator_header(tmp_path):
    """Every firmware folder, not only one: no #include of a firmware_sim header."""
    pat = re.compile(r'#include\s+"(' + "|".join(map(re.escape, SIM_HEADERS)) + ')"')
    for d in vehest_build.FIRMWARE_DIRS:
        for src in sorted(d.glob("*.[ch]")):
            assert not pat.search(src.read_text()), src
    assert set(vehest_build.firmware_include_dirs(tmp_path)).isdisjoint({vehest_build.SIM_INCLUDE_DIR})


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_the_firmware_build_cannot_see_simulator_headers(tmp_path):
    """The boundary is the include path itself: a firmware file that includes a simulator header
    fails to compile in the firmware build (the way vehest_build compiles c_core)."""
    gen = tmp_path / "gen"
    dbcgen.generate_all(gen)
    bad = tmp_path / "bad.c"
    bad.write_text('#include "vh_ecu.h"\n#include "vh_veh14.h"\nint f(void) { return 0; }\n')
    good = tmp_path / "good.c"
    good.write_text('#include "vh_ecu.h"\nint f(void) { return 0; }\n')

    def cc(src, dirs):
        return subprocess.run(["cc", *vehest_build.STRICT_FLAGS, *(f"-I{d}" for d in dirs), "-c", str(src),
                               "-o", str(tmp_path / "x.o")], capture_output=True, text=True)

    assert cc(good, vehest_build.firmware_include_dirs(gen)).returncode == 0
    r = cc(bad, vehest_build.firmware_include_dirs(gen))
    assert r.returncode != 0 and "vh_veh14.h" in r.stderr
    assert cc(bad, vehest_build.sim_include_dirs(gen)).returncode == 0


def test_bench_reaches_the_simulator_only_through_its_declared_path(tmp_path):
    """c_core/bench includes simulator headers by name (never a relative path into firmware_sim),
    so it builds only with vehest_build.bench_include_dirs; the firmware folders never do."""
    assert vehest_build.SIM_INCLUDE_DIR in vehest_build.bench_include_dirs(tmp_path)
    for src in sorted((ROOT / "c_core" / "bench").glob("*.[ch]")):
        code = src.read_text()
        assert "firmware_sim" not in re.sub(r"/\*.*?\*/", "", code, flags=re.S), src
        assert not re.search(r'#include\s+"\.\.?/', code), src
    for d in vehest_build.FIRMWARE_DIRS:
        for src in sorted(d.glob("*.[ch]")):
            assert not re.search(r'#include\s+"\.\.?/', src.read_text()), src


def test_the_ecu_scheduler_stays_thin():
    """vh_ecu.c is the scheduler only (dispatch, runnables, counters): under 200 lines, the rest
    lives in the systems' folders and the SecOC hook."""
    n = len((ROOT / "c_core" / "ecu" / "vh_ecu.c").read_text().splitlines())
    assert n < 200, f"c_core/ecu/vh_ecu.c has {n} lines"
