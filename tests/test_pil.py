"""Processor in the loop: the ECU image (c_core/firmware_image.py) in QEMU's mps2-an386 Cortex-M4F
(and the same sources built for the Cortex-M7 of mps2-an500) against the host build, over the frame
link (vehest_can.service.pil).

The calibration block and the state read back cross the link as raw bytes, so their layout must be
the same on x86-64 and ARM: a dump of every leaf's offset and size, compiled by both compilers. The
golden log replays through the emulated ECU to the golden frames bit for bit, and so does the roll
system's float32 path (its sin/cos/atan are the project's own, c_core/common/vh_mathf.c, the same
bits on both sides: checked here; newlib's and glibc's differ by an ulp). Skipped with the reason
where QEMU or the cross compiler is missing; with CI=true that fails instead (CI installs both:
.ci/apt-packages.txt)."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from vehest_can.bus.frames import message
from vehest_can.bus.log import read_log
from vehest_can.native import ffi, lib
from vehest_can.service import pil
from vehest_can.service.replay import replay
from vehest_can.sim.session import run_inprocess
from vehest_can.systems.ecu import Ecu

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "c_core"))
import cbuild  # noqa: E402
import dbcgen  # noqa: E402
import vehest_build  # noqa: E402

pytestmark = pytest.mark.rebuild  # builds the image with the cross compiler on first use
GOLDEN = ROOT / "tests" / "tireforce" / "data"
ROLL_GOLDEN = ROOT / "tests" / "roll" / "data" / "roll_paper_72kph_active_golden.txt"


def require_pil(why: str | None = None) -> None:
    why = why or pil.missing_tools()
    if why is None:
        return
    message = f"processor-in-the-loop unavailable: {why}"
    if os.environ.get("CI", "").lower() in ("true", "1"):
        pytest.fail(f"{message}\n(CI=true: the PIL tests must run; .ci/apt-packages.txt installs the tools)",
                    pytrace=False)
    pytest.skip(message)


@pytest.fixture(scope="module", params=sorted(pil.MACHINES))
def target(request):
    """The emulated ECU on each core: the Cortex-M4F and the Cortex-M7 beside it."""
    require_pil()
    with pil.PilEcu(measure=True, core=request.param) as ecu:
        yield ecu


# -- the calibration block's layout ----------------------------------------------------------------
def leaves(ctype: str) -> list[tuple[str, str]]:
    """(member designator, C type) of every scalar of a struct, arrays by their first element and
    their whole size, as the host's cffi sees them."""
    out: list[tuple[str, str]] = []

    def walk(t, path: str) -> None:
        if t.kind == "struct":
            for name, f in t.fields:
                walk(f.type, f"{path}.{name}" if path else name)
        elif t.kind == "array":
            out.append((path, "array"))
            walk(t.item, f"{path}[0]")
        else:
            out.append((path, t.cname))
    walk(ffi.typeof(ctype), "")
    return out


def state_type(field: str):
    return dict(ffi.typeof("vh_ecu_t").fields)[field].type


def layout_source() -> tuple[str, int]:
    rows = ["sizeof(vh_ecu_config_t)", "offsetof(vh_ecu_t, xcp)"]
    for path, _ in leaves("vh_ecu_config_t"):
        rows += [f"offsetof(vh_ecu_config_t, {path})", f"sizeof(((vh_ecu_config_t *)0)->{path})"]
    for field in pil.STATE_FIELDS:
        rows += [f"offsetof(vh_ecu_t, {field})", f"sizeof(((vh_ecu_t *)0)->{field})"]
        t = state_type(field)
        if t.kind == "struct":
            for path, _ in leaves(t.cname):
                rows += [f"offsetof(vh_ecu_t, {field}.{path})", f"sizeof(((vh_ecu_t *)0)->{field}.{path})"]
    body = ",\n".join(f"    (uint32_t)({r})" for r in rows)
    src = ('#include <stddef.h>\n#include <stdint.h>\n#include "vh_ecu.h"\n'
           f'__attribute__((section(".vh_layout"), used)) const uint32_t vh_layout[{len(rows)}] = {{\n{body}\n}};\n')
    return src, len(rows)


def dumped(cc: list[str], flags: list[str], objcopy: str, src: Path, gen: Path, n: int) -> np.ndarray:
    obj, raw = src.with_suffix(f".{Path(objcopy).name}.o"), src.with_suffix(f".{Path(objcopy).name}.bin")
    inc = [f"-I{d}" for d in vehest_build.firmware_include_dirs(gen)]
    subprocess.run([*cc, *flags, "-std=c99", *inc, "-c", str(src), "-o", str(obj)], check=True)
    subprocess.run([objcopy, "-O", "binary", "--only-section=.vh_layout", str(obj), str(raw)], check=True)
    out = np.frombuffer(raw.read_bytes(), "<u4")
    assert len(out) == n
    return out


def test_the_calibration_block_and_the_state_have_one_layout_on_host_and_target(tmp_path):
    """Every leaf of vh_ecu_config_t and of the state read back (vh_ecu_t before its XCP slave): offset
    and size from gcc for x86-64 and from arm-none-eabi-gcc for the Cortex-M4F, equal. Their scalars
    are fixed-width types, double and float, and `int` (4 bytes on both ABIs; the dump holds it)."""
    sys.path.insert(0, str(ROOT / "c_core"))
    import firmware_image

    require_pil(firmware_image.missing_toolchain() or (None if shutil.which("arm-none-eabi-objcopy") else
                                                        "arm-none-eabi-objcopy not found (Debian: binutils-arm-none-eabi)"))
    gen = tmp_path / "generated"
    dbcgen.generate_all(gen)
    text, n = layout_source()
    src = tmp_path / "layout.c"
    src.write_text(text)
    host = dumped(cbuild.cc(), [], "objcopy", src, gen, n)
    arm = dumped([cbuild.TARGET_CC], cbuild.TARGET_FLAGS, "arm-none-eabi-objcopy", src, gen, n)
    assert host[0] == ffi.sizeof("vh_ecu_config_t") and host[1] == ffi.offsetof("vh_ecu_t", "xcp")
    assert np.array_equal(host, arm), [i for i in range(n) if host[i] != arm[i]][:10]
    kinds = {c for _, c in leaves("vh_ecu_config_t")}
    kinds |= {c for f in pil.STATE_FIELDS if state_type(f).kind == "struct" for _, c in leaves(state_type(f).cname)}
    fixed = {"double", "float", "array", *(f"{s}int{b}_t" for s in ("", "u") for b in (8, 16, 32, 64))}
    assert kinds - fixed <= {"int"}, kinds - fixed


def test_the_image_holds_no_host_code_and_the_extension_no_board_code(tmp_path):
    """The build boundary both ways: no function of a *_host.c (nor OpenSSL's AES) is in the image, which
    links the target's AES backend instead; no file of c_core/target is in the host's extension."""
    import re

    sys.path.insert(0, str(ROOT / "c_core"))
    import firmware_image

    assert not {p.name for p in vehest_build.TARGET_DIR.glob("*.c")} & \
        {p.name for p in vehest_build.firmware_sources(tmp_path / "gen")}
    require_pil(firmware_image.missing_toolchain())
    host = {name for d in vehest_build.FIRMWARE_DIRS for p in d.glob(vehest_build.HOST_ONLY_GLOB)
            for name in re.findall(r"^[a-z][\w ]*?\b(vh_\w+)\(", p.read_text(), re.M)}
    host -= {"vh_aes128_setkey", "vh_aes128_encrypt"}  # the driver interface: the target's own backend
    assert {"vh_ecu_init", "vh_ecu_config_complete", "vh_skfq_params_from_config"} <= host
    nm = subprocess.run(["arm-none-eabi-nm", "--defined-only", str(firmware_image.image())], check=True,
                        capture_output=True, text=True).stdout
    defined = {ln.split()[-1] for ln in nm.splitlines()}
    assert not host & defined and "AES_encrypt" not in defined
    assert {"vh_ecu_init_params", "vh_ecu_step", "vh_secoc_bus_rx", "vh_reset_handler"} <= defined


# -- the same bits ----------------------------------------------------------------------------------
def test_golden_log_on_the_emulated_ecu_gives_the_golden_frames(target):
    """tests/tireforce/data/chassis_golden.log through the image: every ECU frame (600 ticks: SKFMEC,
    SKFMEC-A, statuses of both buses) equals the host build's, and the golden file's 210."""
    target.reset()
    r = replay(read_log(GOLDEN / "chassis_golden.log"), target)
    host_ecu = Ecu()
    host = replay(read_log(GOLDEN / "chassis_golden.log"), host_ecu)
    assert r.ticks == host.ticks == 600
    assert [(m.arbitration_id, bytes(m.data)) for m in r.produced] == \
        [(m.arbitration_id, bytes(m.data)) for m in host.produced] and len(host.produced) == 840
    ids = {int(x[:3], 16) for x in (GOLDEN / "chassis_golden_expected.txt").read_text().split()}
    got = [f"{m.arbitration_id:03X}#{bytes(m.data).hex().upper()}" for m in r.produced if m.arbitration_id in ids]
    assert got == (GOLDEN / "chassis_golden_expected.txt").read_text().split()
    # the state read back from the target: the same counters, health and heard inputs as the host's
    assert r.counters == host.counters and target.health() == host_ecu.health()
    assert target.heard() == host_ecu.heard() and target.chassis_counters() == host_ecu.chassis_counters()


def test_roll_golden_record_on_the_emulated_ecu(target):
    """The roll loop closed through the image (plant here, UKF and SMC in float32 there): the golden
    record's first 0.5 s bit for bit, plant truth included (the whole record: test_roll_scenarios_...)."""
    from vehest_can.systems.roll.scenario import RollCar, load_roll_scenario

    target.reset()
    sc = load_roll_scenario("roll_paper_72kph_active")
    session = pil.run_pil(RollCar(sc, 0.5), target)
    local = run_inprocess(RollCar(sc, 0.5), Ecu())
    assert np.array_equal(session.frames, local.frames) and np.array_equal(session.truth, local.truth)
    ids = {message("VEHEST_RollCmd").frame_id, message("VEHEST_RollEst").frame_id}
    sel = np.isin(session.frames["id"], list(ids))
    lines = [f"{k} {f['id']:03X}#{bytes(f['data'][: f['len']]).hex().upper()}"
             for f, k in zip(session.frames[sel], session.frame_tick[sel])]
    golden = [ln for ln in ROLL_GOLDEN.read_text().splitlines() if int(ln.split()[0]) < 1000]
    assert lines == golden and len(golden) == 150  # the record's first 0.5 s


def test_a_calibration_set_on_the_host_copy_reaches_the_target(target):
    """The camber calibration (--camber-cal) on the emulated ECU: set by the flashed setter on the host's
    copy of the target's state, written back (longer than one message), read back the same."""
    from vehest_can.systems.camber.api import WHEELS, Calibration, load_into_ecu

    cals = {w: Calibration.identity(0.002 + 0.001 * i) for i, w in enumerate(WHEELS)}
    target.reset()
    target.apply(lambda e: load_into_ecu(e, cals))

    def windows(ecu) -> bytes:  # the four devices' windows, their calibrations in them
        return bytes(ffi.buffer(ffi.addressof(ecu.c.app.camber, "cmb")))

    expected = windows(target)
    ffi.memmove(ffi.addressof(target.c.app.camber, "cmb"), bytes(len(expected)), len(expected))  # forget the copy
    target.read_state()
    assert windows(target) == expected
    host = Ecu()
    load_into_ecu(host, cals)
    assert windows(host) == expected


def test_float_functions_are_the_same_bits_on_host_and_target(target):
    """The float32 functions the firmware calls: vh_mathf's sinf, cosf, atanf, atan2f (c_core/common),
    compiled for the target and for the host, give the same bits on every input (roll's and camber's
    ranges and beyond; sqrtf is correctly rounded on both); and the image links no libm sinf, cosf,
    atanf or atan2f (newlib's round differently from glibc's), so nothing else can call them."""
    rng = np.random.default_rng(7)

    def on_target(fn: int, x: np.ndarray) -> np.ndarray:
        out = []
        for at in range(0, len(x), 2000):  # a message holds at most sizeof(vh_ecu_config_t) bytes
            target._link.queue(b"Q", bytes([fn]) + x[at:at + 2000].astype("<f4").tobytes())
            out.append(np.frombuffer(target._link.answer(b"Q"), "<f4"))
        return np.concatenate(out)

    def bits(a: np.ndarray) -> np.ndarray:
        return np.asarray(a, np.float32).view(np.uint32)

    special = np.array([0.0, -0.0, 1e-30, -1e-30, np.pi / 4, np.pi / 2, np.pi, 8191.0, 2.0 ** 24, np.inf, -np.inf,
                        np.nan], np.float32)
    for fn, name, lo, hi in ((0, "vh_sinf", -10.0, 10.0), (1, "vh_cosf", -10.0, 10.0), (0, "vh_sinf", -8192.0, 8192.0),
                             (2, "vh_atanf", -50.0, 50.0), (2, "vh_atanf", -1e6, 1e6), (4, "sqrtf", 0.0, 1e4)):
        # sqrtf of a negative is the FPU's default NaN, whose sign IEEE leaves open (x86 sets it, ARM not)
        x = np.concatenate([rng.uniform(lo, hi, 20000).astype(np.float32), special[~(special < 0)] if lo >= 0 else special])
        f = getattr(lib, name) if name != "sqrtf" else (lambda v: np.sqrt(np.float32(v)))
        host = np.array([f(float(v)) for v in x], np.float32)
        assert np.array_equal(bits(on_target(fn, x)), bits(host)), name
    x = np.concatenate([rng.uniform(-20.0, 20.0, 40000), [0.0, 1.0, 0.0, -1.0, 1.0, 0.0, -1.0, 0.0, 1e-30, -1.0,
                                                         np.inf, -np.inf, np.nan, 1.0, 1.0, np.nan]])
    x = x.astype(np.float32)
    host = np.array([lib.vh_atan2f(float(a), float(b)) for a, b in x.reshape(-1, 2)], np.float32)
    assert np.array_equal(bits(on_target(3, x)), bits(host))
    import firmware_image

    nm = subprocess.run(["arm-none-eabi-nm", "--defined-only", str(firmware_image.image(core=target.core))], check=True,
                        capture_output=True, text=True).stdout
    linked = {ln.split()[-1] for ln in nm.splitlines()}
    assert not linked & {"sinf", "cosf", "atanf", "atan2f", "sin", "cos", "atan", "atan2"}
    assert {"vh_sinf", "vh_cosf", "vh_atanf", "vh_atan2f"} <= linked


# -- the cost of a tick ------------------------------------------------------------------------------
def test_instruction_counts_and_stack(tmp_path):
    """With -icount shift=0 a SysTick count is 40 instructions (the image's calibration loop says so);
    each system's step has a cost; the painted stack's high-water mark stays inside the stack."""
    require_pil()
    with pil.PilEcu(icount=True, measure=True) as ecu:
        # 200 000 instructions read as 5 000 counts, give or take the one count a read may straddle
        assert pil.calibrate(ecu) == pytest.approx(pil.INSNS_PER_COUNT, abs=0.01)
        replay(read_log(GOLDEN / "chassis_golden.log"), ecu)
        costs = ecu.costs.per_system()
        stack = ecu.stack()
    assert len(costs["tick"]) == 600 and all(costs[s].min() > 0 for s in ("drv", "camber", "tf", "roll", "rx"))
    assert np.all(costs["tick"] >= costs["tf"] + costs["roll"])
    assert 0 < stack["ticks"] < stack["size"] and 0 < stack["init"] < stack["size"]


def test_skfmec_in_fixed_point_and_float32_on_the_target():
    """The measurement behind docs/firmware.md's float32 SKFMEC: the bench image runs the ECU's
    fixed-point step (the same bits as the host's) and the double source built in float32 (within
    0.01 % of each tyre's peak of the double reference) on one scenario; the float32 step costs fewer
    instructions than the fixed-point one."""
    require_pil()
    from vehest_can.tools import skfmec_f32

    r = skfmec_f32.measure(duration_s=0.5)
    assert r["steps"] == 1000 and r["fixed_bits_equal_host"] and r["float32_finite"]
    assert max(r["float32_vs_double_rms_pct"]) < 0.01
    assert 0 < r["float32"]["median"] < r["fixed"]["median"]


# -- the daemon over a bus -----------------------------------------------------------------------------
@pytest.mark.multicast
def test_daemon_with_the_emulated_ecu_in_lockstep_over_the_bus(tmp_path):
    """`vehest-can daemon --target qemu --mode lockstep`: the roll loop closed over udp_multicast through
    the emulated ECU, bit for bit the host's in-process run (0.3 s: its float32 path is identical there);
    the session log replays identically on the host ECU; the daemon's summary is the target's state."""
    import can
    from daemonproc import start_daemon, stop_daemon

    from vehest_can.bus.bus import open_bus, private_multicast
    from vehest_can.sim.session import SimMaster
    from vehest_can.systems.roll.scenario import RollCar, load_roll_scenario

    require_pil()
    sc = load_roll_scenario("roll_paper_72kph_active")
    config = private_multicast()
    proc = start_daemon(config, "--mode", "lockstep", "--target", "qemu", "--idle-timeout", "120", tmp_path=tmp_path)
    try:
        bus = open_bus(config)
        try:
            with can.Logger(str(tmp_path / "sim.log")) as writer:
                session = SimMaster(bus, RollCar(sc, 0.3), log_writer=writer).run_lockstep()
        finally:
            bus.shutdown()
    finally:
        rc, err = stop_daemon(proc)
    assert rc == 0, err
    local = run_inprocess(RollCar(sc, 0.3), Ecu())
    assert len(session.frames) == len(local.frames) > 1000
    assert np.array_equal(session.frames, local.frames) and np.array_equal(session.truth, local.truth)
    r = replay(read_log(tmp_path / "sim.log"))
    assert r.paced_by == "sync" and r.identical
    assert "health: " in err and "roll_ukf=OK" in err
