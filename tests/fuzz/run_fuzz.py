"""Build and run the libFuzzer target for the ECU's RX + tick path (tests/fuzz/fuzz_ecu.c).

    python tests/fuzz/run_fuzz.py --seconds 3600          # a long run (a documented command)
    python tests/fuzz/run_fuzz.py --seconds 20 --jobs 1   # what the suite runs

Built with clang: -fsanitize=fuzzer,address,undefined plus float-cast-overflow (which GCC's
`undefined` leaves out), no recovery: any report is a crash; -O1, the numeric kernels (out of coverage
tracing, coverage_ignore.txt) -O3 with the same sanitizers. The seed corpus is made from the
golden chassis log, the roll golden scenario's sensor frames (roll_paper_72kph_active, in-process),
a clean driveline run (good frames, real CRCs and counters, ticks between), the same roll frames
secured (SecOC mode) and XCP sessions (CONNECT, seed & key, calibration writes, a DAQ list);
every input in tests/fuzz/regressions/ (crashes found earlier) is replayed first. A new crash is
written to the work folder; copy it into regressions/ with its fix.
"""
from __future__ import annotations

import argparse
import fnmatch
import re
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
sys.path.insert(0, str(ROOT / "c_core"))
import vehest_build  # noqa: E402

IGNORELIST = HERE / "coverage_ignore.txt"
SAN = ["-fsanitize=fuzzer,address,undefined,float-cast-overflow", "-fno-sanitize-recover=all",
       "-fno-omit-frame-pointer", "-g", f"-fsanitize-coverage-ignorelist={IGNORELIST}"]
OPT = ["-O1"]
#: the numeric kernels (the ignore list's src: entries, no coverage tracing) are built at -O3, as the
#: extension builds them (vehest_build.OPT_FLAGS), with the same sanitizers: the optimiser changes no
#: coverage guidance there and no result (no -ffast-math, no FMA contraction on plain x86-64), and
#: the roll UKF and tyre-force steps are the maths of every tick
KERNEL_OPT = ["-O3"]
# the harness's RX table: DLS_Sensors, CIS_Accel, CHS_Sensors, ROLL_Sensors/_YawRate/_ActuatorStatus/_ModeCmd,
# CHS_RideHeight
RX_INDEX = {0x100: 0, 0x200: 1, 0x110: 2, 0x120: 3, 0x121: 4, 0x122: 5, 0x123: 6, 0x111: 7}
# the first byte of an input: bit 0 SecOC on, bit 1 XCP MAX_CTO 64
PLAIN, SECOC, CTO64 = 0, 1, 2
TICKS = bytes([2, 0x60])       # op 2: one tick at capacity 6
FULL_TICKS = bytes([2, 0xCF])  # 16 ticks at capacity 12 (VH_ECU_MAX_TX)
SECOC_TAIL = 4


def kernels(sources: list[Path]) -> list[Path]:
    """The sources the coverage ignore list leaves out by file (its src: entries)."""
    globs = [line.split(":", 1)[1].strip() for line in IGNORELIST.read_text().splitlines() if line.startswith("src:")]
    return [s for s in sources if any(fnmatch.fnmatch(str(s), g) for g in globs)]


def build(work: Path, defines: tuple[str, ...] = ()) -> Path:
    clang = shutil.which("clang")
    if clang is None:
        raise RuntimeError("clang is needed (Debian: clang libclang-rt-14-dev)")
    work = work.resolve()  # the kernels compile in work/kernels
    gen = work / "generated"
    names = vehest_build.dbcgen.generate_all(gen)
    firmware = vehest_build.ecu_sources(gen) + [gen / f"{n}.c" for n in names]  # the ECU only: no plant
    exe = work / "fuzz_ecu"
    includes = [f"-I{d}" for d in vehest_build.firmware_include_dirs(gen)]
    common = [clang, "-std=c99", "-Wall", "-Wextra", "-Werror", *SAN, *defines, *includes]
    fast = kernels(firmware)
    if len({k.name for k in fast}) != len(fast):
        raise RuntimeError("two kernels share a file name: their objects would collide")
    objdir = work / "kernels"
    objdir.mkdir(parents=True, exist_ok=True)
    objects = [objdir / f"{k.stem}.o" for k in fast]
    for o in objects:
        o.unlink(missing_ok=True)
    steps = [[*common, *KERNEL_OPT, "-c", *map(str, fast)]] if fast else []
    steps.append([*common, *OPT, *(str(s) for s in firmware if s not in fast), *map(str, objects),
                  str(HERE / "fuzz_ecu.c"), *vehest_build.LINK_FLAGS, "-o", str(exe)])
    for cmd in steps:
        r = subprocess.run(cmd, capture_output=True, text=True, cwd=objdir)
        if r.returncode != 0:
            raise RuntimeError(f"fuzz target build failed:\n{r.stderr}")
    return exe


def _raw(frame_id: int, data: bytes, fd: bool = True) -> bytes:
    """A harness record: op 0 (raw frame) with the RX table's selector, flags, length, payload."""
    return bytes([0, RX_INDEX[frame_id], 6 if fd else 0, len(data)]) + data


def _cro(*data: int) -> bytes:
    """op 4: one CRO frame."""
    return bytes([4, len(data), *data])


def _xcp_session(unlock: int = 0x05) -> bytes:
    """op 5: CONNECT, then seed & key for CAL/PAG (1) and DAQ (4)."""
    return bytes([5 | unlock << 3])


def _roll_frames(duration_s: float = 0.4) -> list[tuple[int, bytes]]:
    """The roll golden scenario's sensor-node frames as the ECU receives them (in-process run)."""
    from vehest_can.sim.session import run_inprocess
    from vehest_can.systems.ecu import Ecu
    from vehest_can.systems.roll.scenario import RollCar, load_roll_scenario

    s = run_inprocess(RollCar(load_roll_scenario("roll_paper_72kph_active"), duration_s), Ecu())
    return [(m.arbitration_id, bytes(m.data)) for m in s.messages() if m.arbitration_id in RX_INDEX]


def _xcp_programs() -> dict[str, bytes]:
    """XCP sessions that reach the commands behind seed & key: a calibration write of the first
    tuning characteristic (its reference value, in range: written in any state), uploads, page
    switching, a DAQ list started."""
    import struct

    from vehest_can.native import ffi
    from vehest_can.systems.ecu import Ecu
    from vehest_can.xcp import ecu as xcp_ecu

    ecu = Ecu()
    desc = xcp_ecu.enable(ecu, bytes(16))  # the layout and the reference page only: no key used here
    item = next(c for c in desc.characteristics if c.safety_class == "tuning")
    off = item.address - desc.calibration_address
    raw = bytes(ffi.buffer(ffi.addressof(ecu.c.xcp, "ref"), ffi.sizeof("vh_ecu_cal_t"))[off:off + item.size])
    meas = desc.measurements[0]
    cal = _xcp_session() + _cro(0xFD) + _cro(0xFA, 0) + _cro(0xFB) + _cro(0xF6, 0, 0, 0, *struct.pack("<I", item.address))
    for i in range(0, len(raw), 6):
        cal += _cro(0xF0, len(raw[i:i + 6]), *raw[i:i + 6])
    cal += (_cro(0xF4, 4, 0, 0, *struct.pack("<I", meas.address)) + _cro(0xF5, 4) + _cro(0xEB, 0x83, 0, 1)
            + _cro(0xEB, 0x83, 0, 0) + FULL_TICKS)
    daq = (_xcp_session() + _cro(0xD6) + _cro(0xD5, 0, 1, 0) + _cro(0xD4, 0, 0, 0, 1) + _cro(0xD3, 0, 0, 0, 0, 2)
           + _cro(0xE2, 0, 0, 0, 0, 0) + _cro(0xE1, 0xFF, 4, 0, *struct.pack("<I", meas.address))
           + _cro(0xE1, 0xFF, 8, 0, *struct.pack("<I", meas.address + 8))
           + _cro(0xE0, 0x10, 0, 0, 0, 0, 1, 0) + _cro(0xDE, 2, 0, 0) + _cro(0xDD, 1) + FULL_TICKS * 4
           + _cro(0xDD, 0) + FULL_TICKS)
    # wrong keys (op bit 7) with the delays between: the lockout; a safety-relevant write (behind the
    # chassis frames of a moving car in seed_corpus: refused outside the safe state)
    wrong = (bytes([0x80 | _xcp_session(0x01)[0]]) + FULL_TICKS * 4) * 5
    burst = desc.item("cal.rx_burst_frames")
    safety = _xcp_session() + _cro(0xF6, 0, 0, 0, *struct.pack("<I", burst.address)) + _cro(0xF0, 1, 16) + FULL_TICKS
    return {"xcp_cal": bytes([PLAIN]) + cal, "xcp_daq": bytes([PLAIN]) + daq,
            "xcp_cal_cto64": bytes([CTO64]) + cal, "xcp_locked": bytes([PLAIN]) + _xcp_session(0) + cal[1:],
            "xcp_lockout": bytes([PLAIN]) + wrong + cal, "xcp_safety": safety}


def _secured(frame_id: int, data: bytes) -> bytes:
    """op 6: the frame's payload (bytes 1.., E2E made by the harness), secured by its node's twin."""
    return bytes([6, RX_INDEX[frame_id], 1]) + data[1:]


def seed_corpus(out: Path, frames_per_seed: int = 64) -> int:
    """Seeds from the golden chassis log (CHS_Sensors with real E2E), the roll golden scenario's
    frames (plain and secured), a synthetic DLS run and XCP sessions."""
    out.mkdir(parents=True, exist_ok=True)
    line = re.compile(r"\(\S+\) \S+ ([0-9A-Fa-f]+)##\d([0-9A-Fa-f]*)")
    frames = []
    for text in (ROOT / "tests" / "tireforce" / "data" / "chassis_golden.log").read_text().splitlines():
        m = line.match(text)
        if m and int(m[1], 16) in RX_INDEX:
            frames.append((int(m[1], 16), bytes.fromhex(m[2])))
    n = 0
    for k, start in enumerate(range(0, min(len(frames), 16 * frames_per_seed), frames_per_seed)):
        part = frames[start:start + frames_per_seed]
        (out / f"chassis_{k:03d}").write_bytes(bytes([PLAIN]) + b"".join(_raw(i, d) + TICKS for i, d in part))
        if k < 4:  # and secured by the harness's chassis node (op 6): the SecOC ECU's chassis path
            (out / f"chassis_secoc_{k:03d}").write_bytes(bytes([SECOC]) + b"".join(_secured(i, d) + TICKS for i, d in part))
            n += 1
        n += 1
    # protected DLS / CIS frames (op 1) with mid-range payloads, ticks between
    for which in (0, 1):
        prog = b"".join(bytes([1, which, 1]) + bytes([0x10, 0x27, 0xF6, 0x09] * 8)[:30] + bytes([2, 0x61])
                        for _ in range(frames_per_seed))
        (out / f"protected_{which}").write_bytes(bytes([PLAIN]) + prog)
        n += 1
    # the roll node's frames as sent (raw, real E2E), and secured by the harness's roll node (op 6)
    roll = _roll_frames()
    for k, start in enumerate(range(0, min(len(roll), 4 * frames_per_seed), frames_per_seed)):
        part = roll[start:start + frames_per_seed]
        (out / f"roll_{k:03d}").write_bytes(bytes([PLAIN]) + b"".join(_raw(i, d) + TICKS for i, d in part))
        (out / f"roll_secoc_{k:03d}").write_bytes(bytes([SECOC]) + b"".join(_secured(i, d) + TICKS for i, d in part))
        n += 2
    for name, prog in _xcp_programs().items():
        if name == "xcp_safety":  # the car moving first: the ECU out of its safe state
            prog = bytes([PLAIN]) + b"".join(_raw(i, d) + TICKS for i, d in frames[:frames_per_seed]) + prog
        (out / name).write_bytes(prog)
        n += 1
    return n


def run(seconds: int, work: Path, jobs: int = 1, seed: int = 1, defines: tuple[str, ...] = (),
        runs: int | None = None, max_len: int = 4096) -> subprocess.CompletedProcess:
    """Fuzz for `seconds` (and, given `runs`, stop each job after that many executions)."""
    work = work.resolve()  # libFuzzer runs in it: a relative path (the default) would not find the target
    work.mkdir(parents=True, exist_ok=True)
    exe = build(work, defines)
    corpus = work / "corpus"
    seed_corpus(corpus)
    regressions = sorted((HERE / "regressions").glob("*"))
    if regressions and not defines:  # replay every crash found before: each must now pass (a canary
        # build is a positive control: a regression input may reach its planted abort)
        r = subprocess.run([str(exe), *map(str, regressions)], capture_output=True, text=True, timeout=300)
        if r.returncode != 0:
            return r
    return subprocess.run([str(exe), str(corpus), f"-max_total_time={seconds}", f"-seed={seed}",
                           f"-jobs={jobs}", f"-workers={jobs}", f"-max_len={max_len}", "-timeout=10",
                           *([f"-runs={runs}"] if runs else []),
                           f"-artifact_prefix={work}/", "-print_final_stats=1"],
                          capture_output=True, text=True, timeout=seconds + 300, cwd=work)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seconds", type=int, default=600)
    p.add_argument("--jobs", type=int, default=1)
    p.add_argument("--runs", type=int, default=None, help="stop each job after this many executions")
    p.add_argument("--max-len", type=int, default=4096, help="the longest input, bytes (libFuzzer -max_len)")
    p.add_argument("--work", default="build/fuzz")
    args = p.parse_args(argv)
    if args.seconds <= 0 or args.jobs <= 0 or args.max_len <= 1 or (args.runs is not None and args.runs <= 0):
        p.error("--seconds, --jobs, --runs must be positive and --max-len at least 2")
    r = run(args.seconds, Path(args.work), args.jobs, runs=args.runs, max_len=args.max_len)
    sys.stdout.write(r.stdout)
    sys.stderr.write(r.stderr[-20000:])
    return r.returncode


if __name__ == "__main__":
    sys.exit(main())
