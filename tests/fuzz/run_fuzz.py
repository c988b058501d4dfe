"""Build and run the libFuzzer target for the ECU's RX + tick path (tests/fuzz/fuzz_ecu.c).

    python tests/fuzz/run_fuzz.py --seconds 3600          # a long run (a documented command)
    python tests/fuzz/run_fuzz.py --seconds 20 --jobs 1   # what the suite runs

Built with clang: -fsanitize=fuzzer,address,undefined plus float-cast-overflow (which GCC's
`undefined` leaves out), no recovery: any report is a crash. The seed corpus is made from the
golden chassis log and a clean driveline run (good frames, real CRCs and counters, ticks between);
every input in tests/fuzz/regressions/ (crashes found earlier) is replayed first. A new crash is
written to the work folder; copy it into regressions/ with its fix.
"""
from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
sys.path.insert(0, str(ROOT / "c_core"))
import vehest_build  # noqa: E402

SAN = ["-fsanitize=fuzzer,address,undefined,float-cast-overflow", "-fno-sanitize-recover=all",
       "-fno-omit-frame-pointer", "-g", "-O1"]
RX_INDEX = {0x100: 0, 0x200: 1, 0x110: 2}  # the harness's RX table: DLS_Sensors, CIS_Accel, CHS_Sensors


def build(work: Path, defines: tuple[str, ...] = ()) -> Path:
    clang = shutil.which("clang")
    if clang is None:
        raise RuntimeError("clang is needed (Debian: clang libclang-rt-14-dev)")
    gen = work / "generated"
    names = vehest_build.dbcgen.generate_all(gen)
    firmware = vehest_build.ecu_sources(gen) + [gen / f"{n}.c" for n in names]  # the ECU only: no plant
    exe = work / "fuzz_ecu"
    includes = [f"-I{d}" for d in vehest_build.firmware_include_dirs(gen)]
    r = subprocess.run([clang, "-std=c99", "-Wall", "-Wextra", "-Werror", *SAN, *defines, *includes,
                        *map(str, firmware), str(HERE / "fuzz_ecu.c"), *vehest_build.LINK_FLAGS, "-o", str(exe)],
                       capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"fuzz target build failed:\n{r.stderr}")
    return exe


def _raw(frame_id: int, data: bytes, fd: bool = True) -> bytes:
    """A harness record: op 0 (raw frame) with the RX table's selector, flags, length, payload."""
    return bytes([0, RX_INDEX[frame_id], 6 if fd else 0, len(data)]) + data


def seed_corpus(out: Path, frames_per_seed: int = 64) -> int:
    """Seeds from the golden chassis log (CHS_Sensors with real E2E) and a synthetic DLS run."""
    out.mkdir(parents=True, exist_ok=True)
    line = re.compile(r"\(\S+\) \S+ ([0-9A-Fa-f]+)##\d([0-9A-Fa-f]*)")
    frames = []
    for text in (ROOT / "tests" / "tireforce" / "data" / "chassis_golden.log").read_text().splitlines():
        m = line.match(text)
        if m and int(m[1], 16) in RX_INDEX:
            frames.append((int(m[1], 16), bytes.fromhex(m[2])))
    n = 0
    for start in range(0, min(len(frames), 16 * frames_per_seed), frames_per_seed):
        prog = b"".join(_raw(i, d) + bytes([2, 0x60]) for i, d in frames[start:start + frames_per_seed])
        (out / f"chassis_{n:03d}").write_bytes(prog)
        n += 1
    # protected DLS / CIS frames (op 1) with mid-range payloads, ticks between
    for which in (0, 1):
        prog = b"".join(bytes([1, which, 1]) + bytes([0x10, 0x27, 0xF6, 0x09] * 8)[:30] + bytes([2, 0x61])
                        for _ in range(frames_per_seed))
        (out / f"protected_{which}").write_bytes(prog)
        n += 1
    return n


def run(seconds: int, work: Path, jobs: int = 1, seed: int = 1,
        defines: tuple[str, ...] = ()) -> subprocess.CompletedProcess:
    work.mkdir(parents=True, exist_ok=True)
    exe = build(work, defines)
    corpus = work / "corpus"
    seed_corpus(corpus)
    regressions = sorted((HERE / "regressions").glob("*"))
    if regressions:  # replay every crash found before: each must now pass
        r = subprocess.run([str(exe), *map(str, regressions)], capture_output=True, text=True, timeout=300)
        if r.returncode != 0:
            return r
    return subprocess.run([str(exe), str(corpus), f"-max_total_time={seconds}", f"-seed={seed}",
                           f"-jobs={jobs}", f"-workers={jobs}", "-max_len=4096", "-timeout=10",
                           f"-artifact_prefix={work}/", "-print_final_stats=1"],
                          capture_output=True, text=True, timeout=seconds + 300, cwd=work)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seconds", type=int, default=600)
    p.add_argument("--jobs", type=int, default=1)
    p.add_argument("--work", default="build/fuzz")
    args = p.parse_args(argv)
    r = run(args.seconds, Path(args.work), args.jobs)
    sys.stdout.write(r.stdout)
    sys.stderr.write(r.stderr[-20000:])
    return r.returncode


if __name__ == "__main__":
    sys.exit(main())
