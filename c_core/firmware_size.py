"""Firmware size and worst-case stack depth of each system for a Cortex-M4F.

Builds every flashed source (``*_host.c`` are host-side calibration helpers and left out) with
``arm-none-eabi-gcc -mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16 -Os`` and prints, per
firmware folder and for the generated CAN codec, text/data/bss (``arm-none-eabi-size``) and the
worst-case stack depth of the folder's deepest entry: the largest sum of frame sizes along any
call chain in GCC's call graph (``-fcallgraph-info=su``, frames from ``-fstack-usage``), across
folders (an application's chain runs on into ``common``). Calls into libgcc/newlib (double
arithmetic is software on an M4F, ``floor``, ``sqrt``, ``memset``) are not in that graph; they
are listed per folder so that the figure is read as "ours + those leaf routines".

Usage: ``python c_core/firmware_size.py [--json]`` (``make firmware-size``).
"""
from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import cbuild  # noqa: E402
import dbcgen  # noqa: E402
import vehest_build  # noqa: E402

CC = cbuild.TARGET_CC
SIZE = "arm-none-eabi-size"
TARGET = [*cbuild.TARGET_FLAGS, "-Os"]

_NODE = re.compile(r'node: \{ title: "([^"]+)" label: "([^"]*)"( shape : ellipse)?')
_FRAME = re.compile(r"(\d+) bytes \((\w+)\)")
_EDGE = re.compile(r'edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"')


def units(gen_dir: Path) -> dict[str, list[Path]]:
    """Sources per row: each firmware folder (without host-only files), and the codec."""
    names = dbcgen.generate_all(gen_dir)
    rows = {d.name: [p for p in sorted(d.glob("*.c")) if not p.match(vehest_build.HOST_ONLY_GLOB)]
            for d in vehest_build.FIRMWARE_DIRS}
    rows["codec (generated)"] = [gen_dir / f"{n}.c" for n in names if n != dbcgen.SIM]
    return rows


def _table_targets(src: Path, fn: str, known: set[str], inc: list[str]) -> set[str]:
    """The functions listed in the static tables that fn indexes (``TABLE[i].member(...)``), in the
    preprocessed source (the scheduler's tables are expanded from the applications' descriptors)."""
    text = subprocess.run([CC, *TARGET, "-E", "-P", *inc, str(src)], check=True, capture_output=True, text=True).stdout
    body = re.search(rf"\b{fn}\([^;{{]*\)\s*\{{(.*?)\n\}}", text, re.S)
    out = set()
    for name, entries in re.findall(r"static const struct \{.*?\} (\w+)\[\] = \{(.*?)\n\};", text, re.S):
        if body and f"{name}[" in body.group(1):
            out |= {f"{src}:{e}" for e in re.findall(r"\b(\w+)\b", entries)} & known
            out |= set(re.findall(r"\b(\w+)\b", entries)) & known
    return out


def measure(tmp: Path) -> tuple[dict, dict[str, set[str]]]:
    """Per row text/data/bss, worst stack and its chain; and the call graph (caller -> callees)."""
    gen = tmp / "generated"
    rows = units(gen)
    inc = [f"-I{d}" for d in vehest_build.firmware_include_dirs(gen)]
    stack: dict[str, int] = {}
    dynamic: set[str] = set()
    calls: dict[str, set[str]] = {}
    external: set[str] = set()
    owner: dict[str, str] = {}
    file_of: dict[str, str] = {}
    out: dict = {}
    for row, srcs in rows.items():
        objs = []
        for src in srcs:
            obj = tmp / "obj" / row.split()[0] / (src.stem + ".o")
            obj.parent.mkdir(parents=True, exist_ok=True)
            subprocess.run([CC, *vehest_build.STRICT_FLAGS, *TARGET, "-ffunction-sections", "-fstack-usage",
                            "-fcallgraph-info=su", *inc, "-c", str(src), "-o", str(obj)],
                           check=True, capture_output=True, text=True, cwd=obj.parent)
            objs.append(obj)
            ci = obj.with_suffix(".ci").read_text()
            for title, label, ext in _NODE.findall(ci):
                if ext:
                    external.add(title)
                    continue
                m = _FRAME.search(label)
                size, kind = (int(m.group(1)), m.group(2)) if m else (0, "")
                stack[title] = size
                file_of[title] = label.split("\\n")[1].rsplit(":", 2)[0] if "\\n" in label else ""
                owner[title] = row
                if kind and kind != "static":
                    dynamic.add(title)
            for a, b in _EDGE.findall(ci):
                calls.setdefault(a, set()).add(b)
        res = subprocess.run([SIZE, "-t", *map(str, objs)], check=True, capture_output=True, text=True).stdout
        lines = res.strip().splitlines()[1:]
        text, data, bss = (int(v) for v in lines[-1].split()[:3])
        files = {Path(ln.split()[-1]).stem + ".c": dict(zip(("text", "data", "bss"), map(int, ln.split()[:3])))
                 for ln in lines[:-1]}
        out[row] = {"text": text, "data": data, "bss": bss, "files": files}

    # A call through a function pointer (the scheduler's RX and runnable tables) is an edge to
    # __indirect_call: resolved to the entries of the tables the caller indexes, so the tick's
    # depth includes its deepest runnable.
    for fn, callees in calls.items():
        if "__indirect_call" in callees and file_of.get(fn):
            callees.discard("__indirect_call")
            callees |= _table_targets(Path(file_of[fn]), fn.rsplit(":", 1)[-1], set(stack), inc)

    memo: dict[str, tuple[int, list[str]]] = {}

    def depth(fn: str, seen: frozenset = frozenset()) -> tuple[int, list[str]]:
        if fn in memo:
            return memo[fn]
        best = (0, [])
        for callee in calls.get(fn, ()):
            if callee in stack and callee not in seen:
                d = depth(callee, seen | {fn})
                best = max(best, d, key=lambda x: x[0])
        res = (stack.get(fn, 0) + best[0], [fn] + best[1])
        memo[fn] = res
        return res

    for row in out:
        fns = [f for f, r in owner.items() if r == row]
        worst = max((depth(f) for f in fns), key=lambda x: x[0], default=(0, []))
        libs = sorted({c for f in fns for c in calls.get(f, ()) if c in external and not c.startswith("vh_")})
        out[row].update({"stack": worst[0], "chain": worst[1], "dynamic": sorted(set(fns) & dynamic), "lib_calls": libs})
    entries = {fn: {"stack": depth(fn)[0], "chain": depth(fn)[1]} for fn in ENTRIES if fn in stack}
    return {"folders": out, "entries": entries}, calls


#: the ECU's entry points: what the stack of a task that runs the firmware must hold
ENTRIES = ("vh_ecu_init_params", "vh_ecu_rx", "vh_ecu_step")


def missing_toolchain() -> str | None:
    """Why the Cortex-M4 build cannot run here (no cross compiler, no newlib headers), or None."""
    if shutil.which(CC) is None or shutil.which(SIZE) is None:
        return f"{CC} not found (Debian: gcc-arm-none-eabi)"
    r = subprocess.run([CC, *TARGET, "-E", "-x", "c", "-"], input="#include <math.h>\n#include <string.h>\n",
                       capture_output=True, text=True)
    return None if r.returncode == 0 else "no newlib headers for arm-none-eabi (Debian: libnewlib-arm-none-eabi)"


def call_graph() -> dict[str, set[str]]:
    """The firmware's call graph (Cortex-M4 build), caller -> callees."""
    with tempfile.TemporaryDirectory() as tmp:
        return measure(Path(tmp))[1]


def reachable(calls: dict[str, set[str]], fn: str) -> set[str]:
    seen, todo = set(), [fn]
    while todo:
        f = todo.pop()
        if f not in seen:
            seen.add(f)
            todo.extend(calls.get(f, ()))
    return seen


def table(all_res: dict, files: bool = False) -> str:
    res = all_res["folders"]
    lines = [f"{'folder':<22} {'text':>7} {'data':>5} {'bss':>5} {'stack':>6}  deepest chain",
             "-" * 82]
    for row, r in res.items():
        chain = " > ".join(f.rsplit(":", 1)[-1] for f in r["chain"][:4]) + (" > ..." if len(r["chain"]) > 4 else "")
        lines.append(f"{row:<22} {r['text']:>7} {r['data']:>5} {r['bss']:>5} {r['stack']:>6}  {chain}")
        if files:
            for name, f in r["files"].items():
                lines.append(f"  {name:<20} {f['text']:>7} {f['data']:>5} {f['bss']:>5}")
    total = {k: sum(r[k] for r in res.values()) for k in ("text", "data", "bss")}
    lines.append("-" * 82)
    lines.append(f"{'total':<22} {total['text']:>7} {total['data']:>5} {total['bss']:>5}")
    lines.append("")
    lines.append("worst-case stack depth of the ECU's entry points [bytes]:")
    for fn, r in all_res["entries"].items():
        chain = " > ".join(f.rsplit(":", 1)[-1] for f in r["chain"])
        lines.append(f"  {fn:<18} {r['stack']:>6}  {chain}")
    lines.append("")
    lines.append("stack: bytes, worst call chain of our code (frames from -fstack-usage, all static);")
    lines.append("plus the leaf routines of libgcc/newlib each folder calls:")
    for row, r in res.items():
        if r["lib_calls"]:
            lines.append(f"  {row}: {', '.join(r['lib_calls'])}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    ap.add_argument("--files", action="store_true", help="also each source file's text/data/bss")
    args = ap.parse_args(argv)
    why = missing_toolchain()
    if why:
        print(f"error: {why}", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as tmp:
        res = measure(Path(tmp))[0]
    print(json.dumps(res, indent=2) if args.json else table(res, args.files))
    return 0


if __name__ == "__main__":
    sys.exit(main())
