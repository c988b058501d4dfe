"""The cost of a tick on the Cortex-M4F: every shipped scenario through the emulated ECU with QEMU's
instruction counting (``-icount shift=0``), per system the instructions of its runnables per tick
(median and worst over its own scenarios), the tick's RX and the whole tick, as cycles at 168 MHz
for a range of cycles per instruction; the painted stack's high-water mark. ``vehest-can bench``
prints it (skipped, with the reason, where QEMU or the cross compiler is missing);
``vehest-can study firmware.cost [--duration S]`` alone.
"""
from __future__ import annotations

import argparse
import math
import sys
from typing import Any

import numpy as np

from ..errors import VehestError

#: the clock of the part the budget is for (an STM32F4-class Cortex-M4F) and the tick
CLOCK_HZ = 168_000_000
TICK_CYCLES = CLOCK_HZ // 2000  # 84,000
#: cycles per instruction of this code on a Cortex-M4F at 168 MHz (docs/firmware.md says why): 1.25 with
#: flash reads hidden by the prefetch (the TRM's timings: loads 2, taken branches 2-4, most others 1),
#: 2.0 where branches miss the flash accelerator (5 wait states at 168 MHz)
CPI = (1.25, 2.0)
SYSTEMS = {"drv": "driveline", "camber": "camber", "tf": "tireforce", "roll": "roll"}


def measure(duration_s: float | None = 1.0, scenarios: list | None = None) -> dict:
    """{"systems": {name: {"median", "worst", "scenarios"}}, "rx", "tick", "overhead", "stack", "calibration"}:
    instructions per tick, each system over the ticks of its own scenarios."""
    from ..service.pil import PilEcu, calibrate, run_pil
    from ..systems import load_any_scenario, shipped_scenarios

    runs = [load_any_scenario(p) for p in (scenarios or shipped_scenarios())]
    per: dict[str, list[np.ndarray]] = {k: [] for k in SYSTEMS}
    names: dict[str, list[str]] = {k: [] for k in SYSTEMS}
    rx, tick, overhead = [], [], []
    busiest: list[tuple[float, int, str]] = []
    deepest = reset_depth = 0
    with PilEcu(icount=True, measure=True) as ecu:
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
    out: dict[str, Any] = {"systems": {}, "calibration": cal, "stack": stack}
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


def profile(scenario, duration_s: float | None = 0.5, top: int = 12) -> tuple[int, list[tuple[str, float]]]:
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
        ecu = PilEcu(profile=out)
        try:
            run_pil(system.car(sc, duration_s), ecu)
            ticks = ecu.tick
        finally:
            ecu.close()
        counts = function_profile(ecu.image, out)
    rows = [(f, n / ticks) for f, n in counts.items() if f not in LINK_FUNCTIONS]
    return ticks, rows[:top]


def table(res: dict) -> str:
    lo, hi = CPI
    lines = [f"Cortex-M4F (QEMU mps2-an386, -icount shift=0; {res['calibration']:.0f} instructions per SysTick count): "
             f"instructions per 500 µs tick, cycles at {CLOCK_HZ / 1e6:.0f} MHz for CPI {lo}..{hi}, share of "
             f"{TICK_CYCLES:,} cycles",
             f"{'':<12} {'median':>8} {'worst':>8}  {'median cycles':>15}  {'% of tick':>11}  {'worst % of tick':>15}"]

    def row(name: str, med: float, worst: int) -> str:
        return (f"{name:<12} {med:>8.0f} {worst:>8d}  {med * lo:>7.0f}..{med * hi:<7.0f}  "
                f"{100 * med * lo / TICK_CYCLES:>4.1f}..{100 * med * hi / TICK_CYCLES:<5.1f}  "
                f"{100 * worst * lo / TICK_CYCLES:>6.1f}..{100 * worst * hi / TICK_CYCLES:<6.1f}")

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
                 f"{'within' if every_med * hi <= TICK_CYCLES / 2 else 'OVER'} 50 % of the tick at the median, CPI {hi})")
    s = res["stack"]
    lines.append(f"stack below main (painted; of {s['size']} B): ticks and frames {s['ticks']} B, reset {s['reset']} B, "
                 f"init {s['init']} B")
    return "\n".join(lines)


def main(argv: list[str], prog: str) -> int:
    ap = argparse.ArgumentParser(prog=prog, description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=None, metavar="S",
                    help="seconds of each scenario (default: all of it)")
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

        if len(args.scenarios) > 1:
            print("--skfmec-float32 takes one scenario", file=sys.stderr)
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
            ticks, rows = profile(path, args.duration or 0.5)
            print(f"{path} ({ticks} ticks): instructions per tick")
            for fn, n in rows:
                print(f"  {fn:<28} {n:>9.0f}")
        return 0
    res = measure(args.duration, args.scenarios or None)
    print(table(res))
    import json

    print(json.dumps(res, indent=2))
    return 0

