"""The ECU as a firmware image for an emulated Cortex-M4F (QEMU's ``mps2-an386`` board), or for a
Cortex-M7 (``mps2-an500``, the same memory map and UART): ``cbuild.CORES``.

Every flashed source (the firmware folders without ``*_host.c``, the generated codec) and the board
support of ``c_core/target/`` (startup, linker script, the UART frame link, main) compiled with
``cbuild.TARGET_CC`` and the core's flags (``-ffp-contract=off`` as on the host), linked
with newlib (nano) and libgcc into an ELF the emulator loads with ``-kernel``. Host-only code cannot
reach the image: it is not compiled, so a flashed call into it is an undefined reference and the
link fails. Each application's runnables are linked through ``--wrap`` (``c_core/target/vh_probe.c``) so
the image can time each application's share of a tick without a line in the scheduler.

``python c_core/firmware_image.py [--core CORE] [--out DIR]`` (``make firmware-image``) builds it and
prints its flash and RAM from the map file, per folder. ``image(core)`` is what the
processor-in-the-loop host (``vehest_can.service.pil``) calls: the image for the current sources,
built once into ``build/firmware-image/<hash>/``.
"""
from __future__ import annotations

import argparse
import hashlib
import re
import shutil
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
import cbuild  # noqa: E402
import dbcgen  # noqa: E402
import vehest_build  # noqa: E402

CC = cbuild.TARGET_CC
#: -O2: the level a production build of this code would use (firmware-size's -Os is the size floor)
OPT = "-O2"
LINKER_SCRIPT = vehest_build.TARGET_DIR / "mps2_an386.ld"
LINK_FLAGS = ["-nostartfiles", "--specs=nano.specs", "--specs=nosys.specs", "-Wl,--gc-sections"]


def image_name(core: str) -> str:
    return f"vehest-ecu-{core}.elf"

#: where image() keeps the images it built (one folder per source hash)
CACHE = ROOT / "build" / "firmware-image"


def missing_toolchain() -> str | None:
    """Why the image cannot be built here (no cross compiler, no newlib), or None."""
    if shutil.which(CC) is None:
        return f"{CC} not found (Debian: gcc-arm-none-eabi)"
    r = subprocess.run([CC, *cbuild.CORES[cbuild.DEFAULT_CORE], "-E", "-x", "c", "-"],
                       input="#include <math.h>\n#include <string.h>\n",
                       capture_output=True, text=True)
    return None if r.returncode == 0 else "no newlib for arm-none-eabi (Debian: libnewlib-arm-none-eabi)"


def sources(gen_dir: Path) -> tuple[list[Path], list[Path]]:
    """(flashed firmware sources with the codec generated into gen_dir, the board support's)."""
    names = dbcgen.generate_all(gen_dir)
    fw = vehest_build.ecu_sources(gen_dir, host=False) + [gen_dir / f"{n}.c" for n in names if n != dbcgen.SIM]
    return fw, sorted(vehest_build.TARGET_DIR.glob("*.c"))


def runnables() -> list[str]:
    """Every application's runnable functions (``vh_<m>_app_<fn>`` of VH_APP_STEP / VH_APP_TX), from the
    descriptors the scheduler is expanded from (c_core/ecu/vh_ecu_apps.inc)."""
    inc = (HERE / "ecu" / "vh_ecu_apps.inc").read_text()
    out = []
    for name in re.findall(r'#include "(\w+\.def)"', inc):
        text = vehest_build.firmware_path(name).read_text()
        out += [f"vh_{m}_app_{fn}" for m, fn in re.findall(r"^VH_APP_(?:STEP|TX)\((\w+),\s*(\w+)", text, re.M)]
    return out


def _inputs_digest(opt: str, core: str) -> str:
    h = hashlib.sha256()
    files = [p for d in (*vehest_build.FIRMWARE_DIRS, vehest_build.TARGET_DIR) for p in sorted(d.iterdir())
             if p.suffix in (".c", ".h", ".inc", ".def", ".ld")]
    files += sorted((ROOT / "dbc").glob("*.dbc")) + [HERE / "dbcgen.py", HERE / "cbuild.py", Path(__file__)]
    for p in files:
        h.update(p.name.encode() + b"\0" + p.read_bytes())
    version = subprocess.run([CC, "--version"], capture_output=True, text=True).stdout.splitlines()[0]
    h.update(" ".join([version, *cbuild.STRICT_FLAGS, *cbuild.CORES[core], opt, *LINK_FLAGS]).encode())
    return h.hexdigest()[:16]


def compile_c(src: Path, obj: Path, includes: list[str], extra: tuple[str, ...] = (), opt: str = OPT,
              core: str = cbuild.DEFAULT_CORE) -> Path:
    """One flashed source to its object with the image's compiler and flags (`includes` as -I options)."""
    obj.parent.mkdir(parents=True, exist_ok=True)
    r = subprocess.run([CC, *cbuild.STRICT_FLAGS, *cbuild.CORES[core], opt, "-ffunction-sections", "-fdata-sections",
                        "-fstack-usage", *extra, *includes, "-c", str(src), "-o", str(obj)], capture_output=True, text=True)
    if r.returncode:
        raise RuntimeError(f"{CC} failed on {src.name}:\n{r.stderr}")
    return obj


def build(out_dir: Path, opt: str = OPT, core: str = cbuild.DEFAULT_CORE) -> Path:
    """Compile and link the image into out_dir; returns the ELF (its map file beside it)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    gen = out_dir / "generated"
    fw, board = sources(gen)
    fw_inc = [f"-I{d}" for d in vehest_build.firmware_include_dirs(gen)]

    def compile_one(src: Path) -> Path:
        folder = src.parent.name if src.parent != gen else "codec"
        inc = fw_inc + ([f"-I{vehest_build.TARGET_DIR}"] if src in board else [])
        return compile_c(src, out_dir / "obj" / folder / (src.stem + ".o"), inc, opt=opt, core=core)

    with ThreadPoolExecutor(2) as pool:
        objs = list(pool.map(compile_one, fw + board))
    elf = out_dir / image_name(core)
    wraps = [f"-Wl,--wrap={fn}" for fn in runnables()]
    r = subprocess.run([CC, *cbuild.CORES[core], *LINK_FLAGS, *wraps, "-T", str(LINKER_SCRIPT),
                        f"-Wl,-Map={elf.with_suffix('.map')}", *map(str, objs), "-lm", "-o", str(elf)],
                       capture_output=True, text=True)
    if r.returncode:
        raise RuntimeError(f"linking the image failed:\n{r.stderr}")
    return elf


def image(opt: str = OPT, core: str = cbuild.DEFAULT_CORE) -> Path:
    """The image of the current sources for `core`, built once (``build/firmware-image/<hash>/``)."""
    why = missing_toolchain()
    if why:
        raise RuntimeError(why)
    out = CACHE / _inputs_digest(opt, core)
    elf = out / image_name(core)
    if not elf.exists():
        CACHE.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=CACHE) as tmp:
            built = build(Path(tmp) / "img", opt, core)
            try:
                built.parent.rename(out)  # atomic: a process building the same image at once keeps its own
            except OSError:
                if not elf.exists():
                    raise
    return elf


_SECTION = re.compile(r"^ (\.(?:text|rodata|data|bss)[\w.]*|COMMON)\s*(?:\n\s+)?(0x[0-9a-f]+)\s+(0x[0-9a-f]+)\s+(\S+)$", re.M)


def memory(elf: Path) -> dict:
    """Flash and RAM of the image from its map file: per owner (a firmware folder, the codec, the board
    support, libgcc/newlib), text+rodata (flash), data (flash and RAM), bss (RAM); and the stack."""
    text = elf.with_suffix(".map").read_text()
    text = text[text.index("Linker script and memory map"):]
    owners: dict[str, dict[str, int]] = {}
    for kind, addr, size, obj in _SECTION.findall(text):
        size_i, addr_i = int(size, 16), int(addr, 16)
        if not size_i or not addr_i:
            continue  # discarded by --gc-sections
        if "/obj/" in obj:
            owner = obj.split("/obj/")[1].split("/")[0]
        else:
            owner = "libgcc/newlib"
        kind = "bss" if kind == "COMMON" or kind.startswith(".bss") else "data" if kind.startswith(".data") else "flash"
        row = owners.setdefault(owner, {"flash": 0, "data": 0, "bss": 0})
        row[kind] += size_i
    stack = int(re.search(r"VH_STACK_SIZE = (0x[0-9a-f]+|\d+)", text).group(1), 0) if "VH_STACK_SIZE" in text else 0
    return {"owners": owners, "stack": stack}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--core", choices=sorted(cbuild.CORES), default=cbuild.DEFAULT_CORE,
                    help=f"the core to build for (default {cbuild.DEFAULT_CORE})")
    ap.add_argument("--out", type=Path, help="build into DIR (default: build/firmware-image/<hash>/)")
    args = ap.parse_args(argv)
    why = missing_toolchain()
    if why:
        print(f"error: {why}", file=sys.stderr)
        return 1
    elf = build(args.out, core=args.core) if args.out else image(core=args.core)
    mem = memory(elf)
    print(f"{elf}")
    print(f"{'owner':<16} {'flash':>8} {'data':>6} {'bss':>7}")
    for owner, r in mem["owners"].items():
        print(f"{owner:<16} {r['flash']:>8} {r['data']:>6} {r['bss']:>7}")
    tot = {k: sum(r[k] for r in mem["owners"].values()) for k in ("flash", "data", "bss")}
    print(f"{'total':<16} {tot['flash']:>8} {tot['data']:>6} {tot['bss']:>7}   stack {mem['stack']}")
    print(f"flash {tot['flash'] + tot['data']} bytes, RAM {tot['data'] + tot['bss'] + mem['stack']} bytes (with the stack)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
