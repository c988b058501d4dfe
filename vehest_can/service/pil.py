"""Processor in the loop: the ECU firmware cross-compiled for a Cortex-M4F, run in QEMU's
``mps2-an386`` board (or for a Cortex-M7 in ``mps2-an500``: :data:`MACHINES`), behind the same face as
:class:`vehest_can.systems.ecu.Ecu`.

The image (``c_core/firmware_image.py``) talks over its UART0, which QEMU connects to a Unix socket
this process listens on (docs/firmware.md, "Processor in the loop"): the calibration block (the
flashed ``vh_ecu_config_t``, completed here as ``vh_ecu_init`` completes it on the host) at start,
then frames in, a tick, the tick's frames out. The daemon, ``replay`` and the in-process loop drive
a :class:`PilEcu` like an ``Ecu``; nothing about them changes but the backend.

What it reads back: every frame the image sends, the tick, and the ECU's state (counters, health,
which sensor frames were heard) copied from the target's ``vh_ecu_t`` on demand (the members before
the XCP slave, laid out alike on both sides: tests/test_pil.py). SecOC and XCP are in the image but
cannot be switched on in it (no AES backend on the emulated board): asking for them is an error.

An emulator's time is not the target's: QEMU runs the instructions as fast as the host lets it, a
tick takes what it takes here. Lockstep only. With ``icount`` (``-icount shift=0``) QEMU's virtual
clock counts instructions, and the SysTick counts the image reports around each runnable become
instructions (:data:`INSNS_PER_COUNT`): the cost of a tick, not its time.
"""
from __future__ import annotations

import os
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ConfigError, VehestError
from ..native import ffi, lib
from ..systems.ecu import Ecu, EcuConfig, check_car

#: the source checkout's C core: the image is built from it (an installed wheel has no c_core/)
C_CORE = Path(__file__).resolve().parents[2] / "c_core"
QEMU = "qemu-system-arm"
#: the QEMU board of each core the image is built for (c_core/cbuild.py CORES); both boards have the same
#: memory map, CMSDK UART0 and SysTick clock
MACHINES = {"cortex-m4f": "mps2-an386", "cortex-m7": "mps2-an500"}
DEFAULT_CORE = "cortex-m4f"
#: SysTick runs on the board's 25 MHz clock; with -icount shift=0 one instruction is 1 ns of virtual
#: time, so one count is 40 instructions (checked by the image's calibration loop, 'K')
INSNS_PER_COUNT = 40
#: steps sent before their answers are read (their answers fit the socket's buffer: no deadlock)
PIPELINE_STEPS = 32
#: the ECU's state the host can read: vh_ecu_t up to its XCP slave (pointers after it differ in size)
STATE_FIELDS = ("app", "cnt", "sig", "tick", "rx_burst_frames")


class PilError(VehestError):
    """The emulated ECU failed: QEMU missing or exited, a fault, a broken link."""


def missing_tools() -> str | None:
    """Why processor-in-the-loop cannot run here (no QEMU, no cross compiler or newlib), or None."""
    if shutil.which(QEMU) is None:
        return f"{QEMU} not found (Debian: qemu-system-arm)"
    if not (C_CORE / "firmware_image.py").exists():
        return "no c_core/ beside the package: the image is built from a source checkout"
    sys.path.insert(0, str(C_CORE))
    import firmware_image

    return firmware_image.missing_toolchain()


def firmware_image(core: str = DEFAULT_CORE) -> Path:
    """The ECU image of the current sources for `core` (built on first use, kept under build/firmware-image/)."""
    sys.path.insert(0, str(C_CORE))
    import firmware_image as fi

    return fi.image(core=core)


def _frame_bytes(f) -> bytes:
    n = int(f.len)
    return struct.pack("<IBB", int(f.id), int(f.flags), n) + bytes(ffi.buffer(f.data)[:n])


class _Link:
    """QEMU with the image, its UART0 on a Unix socket: messages of type, u16 length, payload."""

    def __init__(self, image: Path, *, icount: bool, profile: Path | None = None, core: str = DEFAULT_CORE):
        why = missing_tools()
        if why:
            raise PilError(f"processor-in-the-loop unavailable: {why}")
        self._dir = tempfile.TemporaryDirectory(prefix="vehest-pil-")
        path = os.path.join(self._dir.name, "uart0")
        srv = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        srv.bind(path)
        srv.listen(1)
        self.proc = subprocess.Popen(qemu_command(image, f"unix:{path}", icount=icount, profile=profile, core=core),
                                     stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        srv.settimeout(30.0)
        try:
            self.sock: socket.socket | None
            self.sock, _ = srv.accept()
        except OSError as exc:
            self.close()
            raise PilError(f"QEMU did not connect its UART: {exc}; {self._stderr()}") from exc
        finally:
            srv.close()
        self.sock.settimeout(None)
        self._buf = bytearray()
        self._out = bytearray()

    def _stderr(self) -> str:
        if self.proc.poll() is None:
            return "QEMU still running"
        err = self.proc.stderr.read().decode(errors="replace").strip() if self.proc.stderr else ""
        return f"QEMU exited {self.proc.returncode}" + (f": {err}" if err else "")

    def queue(self, kind: bytes, payload: bytes = b"") -> None:
        self._out += kind + struct.pack("<H", len(payload)) + payload

    def flush(self) -> None:
        if self._out:
            assert self.sock is not None, "the link is closed"
            try:
                self.sock.sendall(self._out)
            except OSError as exc:
                raise PilError(f"link to the emulated ECU broken: {exc}; {self._stderr()}") from exc
            self._out.clear()

    def _read(self, n: int) -> bytes:
        while len(self._buf) < n:
            assert self.sock is not None, "the link is closed"
            try:
                chunk = self.sock.recv(1 << 16)
            except OSError as exc:
                raise PilError(f"link to the emulated ECU broken: {exc}; {self._stderr()}") from exc
            if not chunk:
                raise PilError(f"the emulated ECU closed its link; {self._stderr()}")
            self._buf += chunk
        out = bytes(self._buf[:n])
        del self._buf[:n]
        return out

    def answer(self, kind: bytes) -> bytes:
        """The next message's payload; it must be of this kind."""
        self.flush()
        head = self._read(3)
        payload = self._read(struct.unpack_from("<H", head, 1)[0])
        if head[:1] == b"F":
            raise PilError("the emulated ECU faulted (HardFault or another exception)")
        if head[:1] != kind:
            raise PilError(f"the emulated ECU answered {head[:1]!r} {payload[:16]!r}, expected {kind!r}")
        return payload

    def close(self) -> None:
        sock, self.sock = getattr(self, "sock", None), None
        if sock is not None:
            sock.close()
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        if self.proc.stderr:
            self.proc.stderr.close()
        self._dir.cleanup()


@dataclass
class TickCosts:
    """SysTick counts the image measured, one row per tick: each application's runnables (its step and
    its TX frames), the whole vh_ecu_step, and the tick's vh_ecu_rx calls."""
    owners: list[str]
    rows: list = field(default_factory=list)

    def array(self) -> np.ndarray:
        return np.array(self.rows, dtype=np.int64).reshape(-1, len(self.owners) + 2)

    def per_system(self) -> dict[str, np.ndarray]:
        """Instructions per tick (with icount): each application, the RX of the tick's frames, the
        scheduler's own (the loop, XCP's hooks, SecOC and XCP TX) and the whole tick."""
        a = self.array() * INSNS_PER_COUNT
        n = len(self.owners)
        out = {owner: a[:, i] for i, owner in enumerate(self.owners)}
        out["scheduler"] = a[:, n] - a[:, :n].sum(axis=1)
        out["rx"] = a[:, n + 1]
        out["tick"] = a[:, n] + a[:, n + 1]
        return out


class PilEcu(Ecu):
    """The ECU in the emulator: ``rx``/``rx_frame``, ``step``/``step_frames``, ``reset`` and the
    readers of :class:`~vehest_can.systems.ecu.Ecu`, over the frame link. ``costs`` collects the
    image's per-runnable counts when ``measure`` is on (meaningful as instructions with ``icount``)."""

    def __init__(self, config: EcuConfig | None = None, *, icount: bool = False, measure: bool = False,
                 image: Path | None = None, profile: Path | None = None, core: str = DEFAULT_CORE):
        if core not in MACHINES:
            raise ConfigError(f"core {core!r}: one of {', '.join(MACHINES)}")
        self.config = config or EcuConfig.default()
        cfg = self.config.to_c()
        if lib.vh_ecu_config_complete(cfg) != lib.VH_OK:  # completed in place: the calibration block
            if self.config.car is not None:
                check_car(self.config.car, plant=False)  # names the car's key when it is the car
            raise ConfigError("ECU configuration: invalid configuration value")
        super().__init__(self.config)  # the host's ECU: the state mirror (and the same checks)
        self.icount = icount
        self.measure = measure
        self.core = core
        self.image = image or firmware_image(core)
        #: with a file: the instructions QEMU executed per function, written there when the ECU is closed
        #: (function_profile reads it)
        self.profile = profile
        self._link = _Link(self.image, icount=icount, profile=profile, core=core)
        try:
            hello = self._link_hello()
            if hello["config_size"] != ffi.sizeof("vh_ecu_config_t"):
                raise PilError(f"the image's vh_ecu_config_t is {hello['config_size']} bytes, the host's "
                               f"{ffi.sizeof('vh_ecu_config_t')}: not the same calibration layout")
            self.costs = TickCosts(hello["owners"])
            self._link.queue(b"I", bytes(ffi.buffer(cfg)))
            status, _, self.init_stack = struct.unpack("<iII", self._link.answer(b"I"))
            if status != lib.VH_OK:
                raise PilError(f"the emulated ECU refused its calibration block (vh_ecu_init_params: {status})")
        except BaseException:
            self._link.close()
            raise
        self._tick = 0
        self._state_end = ffi.offsetof("vh_ecu_t", "xcp")
        self._pending_steps = 0

    def _link_hello(self) -> dict:
        self._link.queue(b"H")
        p = self._link.answer(b"H")
        config_size, ecu_size, n = struct.unpack_from("<IIH", p)
        owners = [s.decode() for s in p[10:].split(b"\0")[:n]]
        return {"config_size": config_size, "ecu_size": ecu_size, "owners": owners}

    # -- the ECU's face ---------------------------------------------------------------------------
    def enable_secoc(self, keys: dict, store=None):
        raise ConfigError("SecOC cannot run on the emulated ECU: the board has no AES backend (a real ECU "
                          "links its HSM driver); run the host ECU for SecOC")

    def rx_frame(self, frame) -> None:
        self._link.queue(b"R", _frame_bytes(frame))

    def step_frames(self) -> list:
        self._link.queue(b"S")
        return self._step_answer()

    def _step_answer(self) -> list:
        p = self._link.answer(b"T")
        self._tick, n = struct.unpack_from("<IB", p)
        self._tick += 1
        pos = 5
        for i in range(n):
            fid, flags, ln = struct.unpack_from("<IBB", p, pos)
            f = self._tx[i]
            f.id, f.flags, f.len = fid, flags, ln
            ffi.memmove(f.data, p[pos + 6:pos + 6 + ln].ljust(64, b"\0"), 64)
            pos += 6 + ln
        m = p[pos]
        if self.measure:
            self.costs.rows.append(struct.unpack_from(f"<{m}I", p, pos + 1))
        self._steps += 1
        return [self._tx[i] for i in range(n)]

    def reset(self) -> None:
        self._link.queue(b"Z")
        self._link.answer(b"Z")
        self._tick = 0

    def note_deadline_miss(self, n: int = 1) -> None:
        raise ConfigError("the emulated ECU runs in lockstep only: an emulator's time is not the target's")

    @property
    def tick(self) -> int:
        return self._tick

    # -- the target's state, read back -------------------------------------------------------------
    def read_state(self) -> None:
        """Copy the target's vh_ecu_t (up to the XCP slave) into the host mirror ``self.c``."""
        buf = bytearray()
        while len(buf) < self._state_end:
            n = min(0xF000, self._state_end - len(buf))
            self._link.queue(b"M", struct.pack("<II", len(buf), n))
            buf += self._link.answer(b"M")
        ffi.memmove(self.c, bytes(buf), len(buf))

    def write_state(self) -> None:
        """Copy the host mirror's vh_ecu_t (up to the XCP slave) into the target."""
        data = bytes(ffi.buffer(self.c, self._state_end))
        chunk = ffi.sizeof("vh_ecu_config_t") - 4  # the image takes messages up to its calibration block's size
        for at in range(0, len(data), chunk):
            self._link.queue(b"P", struct.pack("<I", at) + data[at:at + chunk])
            self._link.answer(b"P")

    def apply(self, change) -> None:
        """``change(ecu)`` on the target's state: read back, changed on the host's copy (e.g. by a flashed
        setter such as the camber calibration's), written to the target."""
        self.read_state()
        change(self)
        self.write_state()

    def poll_counters(self) -> None:
        self.read_state()

    def counters(self) -> dict[str, int]:
        self.read_state()
        return self._own.poll()

    def heard(self) -> dict[str, bool]:
        self.read_state()
        return super().heard()

    def not_heard(self) -> list[str]:
        self.read_state()
        return super().not_heard()

    def health(self) -> dict[str, str]:
        self.read_state()
        return super().health()

    def system_counters(self, name: str) -> dict[str, int]:
        self.read_state()
        return self._sets[name].poll()

    def stack(self) -> dict[str, int]:
        """The deepest stack below main since the calibration (painted; 'W' repaints), main's own depth
        and the stack's size, in bytes; and what init used."""
        self._link.queue(b"W")
        deepest, main_depth, size = struct.unpack("<III", self._link.answer(b"W"))
        return {"ticks": deepest, "main": main_depth, "size": size, "init": self.init_stack}

    # -- batches (replay) ---------------------------------------------------------------------------
    def replay_run(self, frames: np.ndarray, op: np.ndarray, steps: np.ndarray, n: int, pos,
                   out: np.ndarray, out_event: np.ndarray, out_step: np.ndarray, cap: int) -> int:
        """vh_replay_run (firmware_sim/include/vh_replay.h) over the link: events pos.event..n-1, each its
        steps then its frame or reset; answers read PIPELINE_STEPS at a time."""
        written = 0
        waiting: list[tuple[int, int]] = []  # (event, step) of the steps sent and not yet answered

        def collect() -> None:
            nonlocal written
            for ev, st in waiting:
                for f in self._step_answer():
                    rec = out[written]
                    rec["id"], rec["len"], rec["flags"] = f.id, f.len, f.flags
                    rec["data"] = np.frombuffer(ffi.buffer(f.data), np.uint8)
                    out_event[written], out_step[written] = ev, st
                    written += 1
            waiting.clear()

        while pos.event < n:
            i = pos.event
            while pos.step < steps[i]:
                if cap - written - len(waiting) * lib.VH_ECU_MAX_TX < lib.VH_ECU_MAX_TX:
                    collect()
                    if cap - written < lib.VH_ECU_MAX_TX:
                        return written
                    continue
                self._link.queue(b"S")
                waiting.append((i, pos.step))
                pos.step += 1
                if len(waiting) >= PIPELINE_STEPS:
                    collect()
            if op[i] == lib.VH_REPLAY_RX:
                f = frames[i]
                ln = int(f["len"])
                self._link.queue(b"R", struct.pack("<IBB", int(f["id"]), int(f["flags"]), ln) + f["data"][:ln].tobytes())
            elif op[i] == lib.VH_REPLAY_RESET:
                collect()
                self.reset()
            pos.event += 1
            pos.step = 0
        collect()
        return written

    def close(self) -> None:
        self._link.close()

    def __enter__(self) -> PilEcu:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def qemu_command(image: Path, serial: str, *, icount: bool, profile: Path | None = None,
                 core: str = DEFAULT_CORE) -> list[str]:
    """QEMU's command line for an image on the core's board, UART0 on the chardev `serial` (e.g.
    ``unix:PATH``, ``file:PATH``); with ``icount`` one instruction per ns of virtual time; with `profile`
    the instruction-count plugin writing there."""
    cmd = [QEMU, "-M", MACHINES[core], "-display", "none", "-monitor", "none", "-serial", serial, "-kernel", str(image)]
    if icount:
        cmd += ["-icount", "shift=0"]
    if profile is not None:
        cmd += ["-plugin", f"{insn_profile_plugin()},out={profile}"]
    return cmd


def insn_profile_plugin() -> Path:
    """QEMU's TCG plugin that counts the instructions executed per block (c_core/target/qemu_plugin), built
    for this host once."""
    sys.path.insert(0, str(C_CORE))
    import cbuild

    src = C_CORE / "target" / "qemu_plugin" / "vh_insn_profile.c"
    import hashlib

    out = C_CORE.parent / "build" / "qemu-plugin" / f"vh_insn_profile-{hashlib.sha256(src.read_bytes()).hexdigest()[:12]}.so"
    if not out.exists():
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = out.with_suffix(f".{os.getpid()}.tmp")
        subprocess.run([*cbuild.cc(), "-std=c11", "-O2", "-Wall", "-Wextra", "-Werror", "-shared", "-fPIC",
                        "-fvisibility=hidden", str(src), "-o", str(tmp)], check=True, capture_output=True)
        tmp.replace(out)
    return out


def function_profile(image: Path, profile: Path) -> dict[str, int]:
    """Instructions executed per function of the image (the plugin's blocks, by their start address)."""
    nm = subprocess.run(["arm-none-eabi-nm", "-S", "--defined-only", str(image)], check=True, capture_output=True,
                        text=True).stdout
    funcs = sorted((int(a, 16) & ~1, int(sz, 16), name) for a, sz, kind, name in
                   (ln.split() for ln in nm.splitlines() if len(ln.split()) == 4) if kind in "tTwW")
    starts = [f[0] for f in funcs]
    import bisect

    out: dict[str, int] = {}
    for line in profile.read_text().splitlines():
        addr, n = (int(v, 16) if i == 0 else int(v) for i, v in enumerate(line.split()))
        i = bisect.bisect_right(starts, addr) - 1
        name = funcs[i][2] if i >= 0 and addr < funcs[i][0] + max(funcs[i][1], 2) else f"0x{addr:x}"
        out[name] = out.get(name, 0) + n
    return dict(sorted(out.items(), key=lambda kv: -kv[1]))


def calibrate(ecu: PilEcu, iterations: int = 100_000) -> float:
    """Instructions per SysTick count, measured: the image runs a loop of 2 instructions per iteration
    between two SysTick reads ('K'). 40 with ``-icount shift=0`` (25 MHz SysTick, 1 ns per instruction)."""
    ecu._link.queue(b"K", struct.pack("<I", iterations))
    counts, = struct.unpack("<I", ecu._link.answer(b"K"))
    return 2 * iterations / counts if counts else float("inf")


def run_pil(car, ecu: PilEcu):
    """vh_lockstep_run (firmware_sim/include/vh_car.h) with the emulated ECU: per tick the car's frames
    into the ECU, its tick, its frames back to the car; a Session like ``run_inprocess``'s."""
    import time

    from ..bus.frames import FRAME_DTYPE
    from ..sim.session import Session

    car.reset()
    n = car.n
    raw = np.zeros(n, dtype=car.c_truth_dtype)
    raw_b = ffi.from_buffer(raw)
    size = raw.dtype.itemsize
    buf = ffi.new("vh_frame_t[]", lib.VH_CAR_MAX_TX)
    max_car = min(car.c.max_tx, lib.VH_CAR_MAX_TX)
    frames = np.zeros(n * 4 + 1024, FRAME_DTYPE)
    ticks = np.zeros(len(frames), np.uint32)
    m = 0
    t0 = time.perf_counter()

    def keep(f, k) -> None:
        nonlocal frames, ticks, m
        if m == len(frames):
            frames = np.concatenate((frames, np.zeros(len(frames), FRAME_DTYPE)))
            ticks = np.concatenate((ticks, np.zeros(len(ticks), np.uint32)))
        ffi.memmove(ffi.from_buffer(frames[m:m + 1]), ffi.addressof(f), ffi.sizeof("vh_frame_t"))
        ticks[m] = k
        m += 1

    for k in range(n):
        ncar = lib.vh_car_tick(car.c, k, buf, max_car)
        for i in range(ncar):
            ecu.rx_frame(buf[i])
        out = ecu.step_frames()
        for i in range(ncar):
            keep(buf[i], k)
        for f in out:
            lib.vh_car_rx(car.c, ffi.addressof(f))
            keep(f, k)
        ffi.memmove(raw_b + k * size, lib.vh_car_truth(car.c), size)
        if (k + 1) % 2000 == 0 and k + 1 < n:
            car.maintain()
    wall = time.perf_counter() - t0
    return Session(car.name, "pil", car.truths(raw), frames[:m].copy(), ticks[:m].copy(),
                   stats={"wall_s": wall, "realtime_factor": n * 5e-4 / wall if wall else float("inf"),
                          "counters": ecu.counters(), "chassis_counters": ecu.chassis_counters(),
                          "health": ecu.health()})


__all__ = ["PilEcu", "PilError", "TickCosts", "calibrate", "firmware_image", "function_profile", "insn_profile_plugin",
           "missing_tools", "run_pil"]
