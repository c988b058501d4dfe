"""The cost of a tick on the Cortex-M4F (or the Cortex-M7 beside it): every shipped scenario through the
emulated ECU with QEMU's instruction counting (``-icount shift=0``), per system the instructions of its
runnables per tick (median and worst over its own scenarios), the tick's RX and the whole tick, as
cycles at the part's clock (168 MHz; 400 MHz) for a range of cycles per instruction; the painted
stack's high-water mark. ``vehest-can bench`` prints it for both cores (skipped, with the reason, where
QEMU or the cross compiler is missing); ``vehest-can study firmware.cost [--core CORE] [--duration S]``
alone.
"""
from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import VehestError


@dataclass(frozen=True)
class Part:
    """The part a core's budget is for: its clock and the cycles per instruction of this code on it."""
    name: str
    clock_hz: int
    cpi: tuple[float, float]

    @property
    def tick_cycles(self) -> int:
        return self.clock_hz // 2000  # the 500 µs tick


#: docs/firmware.md says why. Cortex-M4F at 168 MHz (STM32F4-class): CPI 1.25 with flash reads hidden by
#: the prefetch (the TRM's timings: loads 2, taken branches 2-4, most others 1), 2.0 where branches miss
#: the flash accelerator (5 wait states at 168 MHz). Cortex-M7 at 400 MHz (the class of an automotive
#: M7, e.g. NXP S32G's): the M4F's range times 3.40 / 5.01, the two cores' published CoreMark/MHz (the
#: M7 issues two instructions per cycle where it can): an estimate, not a measurement
PARTS = {
    "cortex-m4f": Part("Cortex-M4F", 168_000_000, (1.25, 2.0)),
    "cortex-m7": Part("Cortex-M7", 400_000_000, (round(1.25 * 3.40 / 5.01, 2), round(2.0 * 3.40 / 5.01, 2))),
}
CPI = PARTS["cortex-m4f"].cpi
TICK_CYCLES = PARTS["cortex-m4f"].tick_cycles  # 84,000
SYSTEMS = {"drv": "driveline", "camber": "camber", "tf": "tireforce", "roll": "roll"}


def measure(duration_s: float | None = 1.0, scenarios: list | None = None, core: str = "cortex-m4f") -> dict:
    """{"core", "systems": {name: {"median", "worst", "scenarios"}}, "rx", "tick", "overhead", "stack",
    "calibration"}: instructions per tick on `core`, each system over the ticks of its own scenarios."""
    from ..service.pil import PilEcu, calibrate, run_pil
    from ..systems import load_any_scenario, shipped_scenarios

    runs = [load_any_scenario(p) for p in (scenarios or shipped_scenarios())]
    per: dict[str, list[np.ndarray]] = {k: [] for k in SYSTEMS}
    names: dict[str, list[str]] = {k: [] for k in SYSTEMS}
    rx, tick, overhead = [], [], []
    busiest: list[tuple[float, int, str]] = []
    deepest = reset_depth = 0
    with PilEcu(icount=True, measure=True, core=core) as ecu:
        cal = calibrate(ecu)
        for system, sc in runs:
            ecu.stack()  # repainted: the reset's depth next, then the ticks' and frames'
            ecu.reset()
            reset_depth = max(reset_depth, ecu.stack()["ticks"])
            ecu.costs.rows.clear()
            run_pil(system.car(sc, duration_s), ecu)
            c = ecu.costs.per_system()
            key = next(k for k, v in SYSTEMS.items() if v == system.name)
            per[key].append(c[key])
            names[key].append(sc.name)
            rx.append(c["rx"])
            tick.append(c["tick"])
            busiest.append((float(np.median(c["tick"])), int(c["tick"].max()), sc.name))
            overhead.append(c["scheduler"])
            deepest = max(deepest, ecu.stack()["ticks"])
        stack = ecu.stack() | {"ticks": deepest, "reset": reset_depth}
    out: dict[str, Any] = {"core": core, "systems": {}, "calibration": cal, "stack": stack}
    for key, arrays in per.items():
        if arrays:
            a = np.concatenate(arrays)
            out["systems"][SYSTEMS[key]] = {"median": float(np.median(a)), "worst": int(a.max()),
                                            "scenarios": names[key]}
    for name, arrays in (("rx", rx), ("tick", tick), ("scheduler", overhead)):
        a = np.concatenate(arrays)
        out[name] = {"median": float(np.median(a)), "worst": int(a.max())}
    med, worst, name = max(busiest)
    out["busiest"] = {"median": med, "worst": max(w for _, w, _ in busiest), "scenario": name}
    return out


#: the frame link's own code: not the ECU's cost
LINK_FUNCTIONS = frozenset({"main", "vh_uart_get", "vh_uart_put", "vh_uart_read", "vh_uart_write", "do_step", "do_rx",
                            "send", "put_u32", "get_u32", "memcpy"})


def profile(scenario, duration_s: float | None = 0.5, top: int = 12,
            core: str = "cortex-m4f") -> tuple[int, list[tuple[str, float]]]:
    """(ticks, [(function, instructions per tick)]) of one scenario through the emulated ECU, counted per
    function by QEMU's TCG plugin (c_core/target/qemu_plugin): where a system's instructions go. The
    frame link's functions are left out; init's (the gear models' matrix exponential) are spread
    over the ticks."""
    import tempfile
    from pathlib import Path

    from ..service.pil import PilEcu, function_profile, run_pil
    from ..systems import load_any_scenario

    system, sc = load_any_scenario(scenario)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "profile.txt"
        ecu = PilEcu(profile=out, core=core)
        try:
            run_pil(system.car(sc, duration_s), ecu)
            ticks = ecu.tick
        finally:
            ecu.close()
        counts = function_profile(ecu.image, out)
    rows = [(f, n / ticks) for f, n in counts.items() if f not in LINK_FUNCTIONS]
    return ticks, rows[:top]


def table(res: dict) -> str:
    from ..service.pil import MACHINES

    part = PARTS[res["core"]]
    lo, hi = part.cpi
    tick_cycles = part.tick_cycles
    lines = [f"{part.name} (QEMU {MACHINES[res['core']]}, -icount shift=0; {res['calibration']:.0f} instructions per "
             f"SysTick count): instructions per 500 µs tick, cycles at {part.clock_hz / 1e6:.0f} MHz for CPI "
             f"{lo}..{hi}, share of {tick_cycles:,} cycles",
             f"{'':<12} {'median':>8} {'worst':>8}  {'median cycles':>15}  {'% of tick':>11}  {'worst % of tick':>15}"]

    def row(name: str, med: float, worst: int) -> str:
        return (f"{name:<12} {med:>8.0f} {worst:>8d}  {med * lo:>7.0f}..{med * hi:<7.0f}  "
                f"{100 * med * lo / tick_cycles:>4.1f}..{100 * med * hi / tick_cycles:<5.1f}  "
                f"{100 * worst * lo / tick_cycles:>6.1f}..{100 * worst * hi / tick_cycles:<6.1f}")

    for name, r in res["systems"].items():
        lines.append(row(name, r["median"], r["worst"]))
    lines.append(row("rx", res["rx"]["median"], res["rx"]["worst"]))
    lines.append(row("scheduler", res["scheduler"]["median"], res["scheduler"]["worst"]))
    every_med = sum(r["median"] for r in res["systems"].values()) + res["rx"]["median"] + res["scheduler"]["median"]
    every_worst = sum(r["worst"] for r in res["systems"].values()) + res["rx"]["worst"] + res["scheduler"]["worst"]
    lines.append(row("every system", every_med, every_worst))
    b = res["busiest"]
    lines.append(row("busiest", b["median"], b["worst"]) + f"  (measured whole tick: {b['scenario']}'s median, "
                 "the worst tick of any scenario)")
    lines.append(f"(every system: the sum of each system's figures over its own scenarios, all active in one tick; "
                 f"{'within' if every_med * hi <= tick_cycles / 2 else 'OVER'} 50 % of the tick at the median, CPI {hi})")
    s = res["stack"]
    lines.append(f"stack below main (painted; of {s['size']} B): ticks and frames {s['ticks']} B, reset {s['reset']} B, "
                 f"init {s['init']} B")
    return "\n".join(lines)


def main(argv: list[str], prog: str) -> int:
    ap = argparse.ArgumentParser(prog=prog, description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=None, metavar="S",
                    help="seconds of each scenario (default: all of it)")
    ap.add_argument("--core", choices=sorted(PARTS), default="cortex-m4f",
                    help="the core the image is built for and emulated (default cortex-m4f; cortex-m7: the next part "
                         "up, QEMU's mps2-an500)")
    ap.add_argument("--profile", action="store_true",
                    help="instead: the instructions per tick of each function, per scenario (QEMU's TCG plugin)")
    ap.add_argument("--skfmec-float32", action="store_true",
                    help="instead: the SKFMEC step in fixed point (the ECU's) and in float32 (its double source built "
                         "so, not shipped) on one tyre-force scenario (default chassis_paper_mu_drop): instructions "
                         "per step and the float32's accuracy against double")
    ap.add_argument("scenarios", nargs="*", help="scenario files (default: every shipped one)")
    args = ap.parse_args(argv)
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
        print(f"{prog}: --duration must be a finite number of seconds > 0, not {args.duration}", file=sys.stderr)
        return 2
    from ..service.pil import missing_tools

    why = missing_tools()
    if why:
        print(f"processor-in-the-loop unavailable: {why}", file=sys.stderr)
        return 1
    if args.skfmec_float32:
        from . import skfmec_f32

        if len(args.scenarios) > 1 or args.core != "cortex-m4f":
            print("--skfmec-float32 takes one scenario, on the cortex-m4f", file=sys.stderr)
            return 2
        try:
            res = skfmec_f32.measure(args.scenarios[0] if args.scenarios else skfmec_f32.DEFAULT_SCENARIO, args.duration)
        except (VehestError, RuntimeError) as exc:
            print(f"{prog} --skfmec-float32: {exc}", file=sys.stderr)
            return 1
        print(skfmec_f32.table(res, CPI, TICK_CYCLES))
        return 0
    if args.profile:
        from ..systems import shipped_scenarios

        for path in args.scenarios or shipped_scenarios():
            ticks, rows = profile(path, args.duration or 0.5, core=args.core)
            print(f"{path} ({ticks} ticks): instructions per tick")
            for fn, n in rows:
                print(f"  {fn:<28} {n:>9.0f}")
        return 0
    res = measure(args.duration, args.scenarios or None, args.core)
    print(table(res))
    import json

    print(json.dumps(res, indent=2))
    return 0

