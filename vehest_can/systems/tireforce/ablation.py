"""SKFMEC-A against the SKFMEC on every shipped and stress scenario, with each of its additions
switched off in turn (the ablation table of docs/results.md):
``vehest-can study tireforce.ablation [--markdown] [SCENARIO ...]``."""
from __future__ import annotations

import argparse
import sys

from ...errors import ScenarioError
from . import api as tf
from .adaptive import STRESS_DIR, AdaptiveSkfmec
from .report import decode_inputs, evaluate, true_mass
from .scenario import list_tireforce_scenarios, load_tireforce_scenario, tireforce_scenario_dir

ABLATIONS = {"SKFMEC (paper)": None, "SKFMEC-A": {}, "  - no mass estimate (items 1-3)": {"mass": False},
             "  - no load-sensitive split (4)": {"split": False}, "  - no per-side friction (6)": {"friction": False},
             "  - no combined-slip capacity (7)": {"combined": False},
             "  - neither 6 nor 7": {"friction": False, "combined": False},
             "  - no ride-height mass (8)": {"ride": False}, "  - no road friction (9)": {"road": False},
             "  - no ride-height load transfer (10)": {"transfer": False}}


def ablation(sc) -> dict:
    """One scenario: per-tyre and axle RMS error (% of peak |Fy|) of the SKFMEC and of SKFMEC-A with
    each addition switched off in turn, and the mass estimate at the end against the truth."""
    from ...native import ffi, lib

    truth, frames = sc.run_with_frames(ffi, lib)
    dec = decode_inputs(frames)
    u = dec.for_filter()
    runs: dict[str, tf.TireForceRun] = {}
    for label, opts in ABLATIONS.items():
        runs[label] = (tf.estimator(tf.SKFMEC).run(u, dec.mask) if opts is None
                       else AdaptiveSkfmec().with_options(**opts).run(u, dec.mask, dec.ride))
    true = true_mass(sc)
    m = evaluate(truth, runs, true_mass_kg=true)
    mass = m["variants"]["SKFMEC-A"]["mass"]
    return {"scenario": sc.name, "mass_error_pct": 100 * (mass["final_kg"] / true - 1), **m}


def _converged(mass: dict) -> str:
    return f"converged at {mass['converged_s']:.2f} s" if mass["converged_s"] is not None else "not converged"


def ablation_table(m: dict) -> str:
    cols = ("FL", "FR", "RL", "RR", "front", "rear")
    mass = m["variants"]["SKFMEC-A"]["mass"]
    conv = _converged(mass)
    lines = [f"== {m['scenario']}: RMS error after 0.2 s, % of peak |Fy|; mass {mass['final_kg']:.0f} kg, truth "
             f"{m['true_mass_kg']:.0f} kg ({m['mass_error_pct']:+.1f} %), {conv}",
             f"{'':<38}" + "".join(f"{c:>8}" for c in cols)]
    for v, vm in m["variants"].items():
        lines.append(f"{v:<38}" + "".join(f"{vm['rms_pct'][c]:>8.2f}" for c in cols))
    return "\n".join(lines)


def markdown_row(m: dict) -> str:
    """One scenario as a row of docs/results.md's ablation table: per variant FL / FR / RL / RR; front / rear."""
    mass = m["variants"]["SKFMEC-A"]["mass"]
    conv = _converged(mass)
    cells = [" / ".join(f"{vm['rms_pct'][w]:.2f}" for w in ("FL", "FR", "RL", "RR")) + "; "
             + " / ".join(f"{vm['rms_pct'][a]:.2f}" for a in ("front", "rear")) for vm in m["variants"].values()]
    return (f"| `{m['scenario']}` | " + " | ".join(cells) + f" | {mass['final_kg']:.0f} kg ({m['true_mass_kg']:.0f}: "
            f"{m['mass_error_pct']:+.1f} %), {conv} |")


def markdown_header() -> str:
    labels = [v.strip().removeprefix("- ").replace("no ", "− ", 1).replace("neither 6 nor 7", "− 6 and 7")
              for v in ABLATIONS]
    return ("| run | " + " | ".join(labels) + " | mass at the end (truth) |\n"
            + "|---" * (len(labels) + 2) + "|")


def main(argv: list[str], prog: str) -> int:
    ap = argparse.ArgumentParser(prog=prog, description="SKFMEC-A against the SKFMEC, with its ablations")
    ap.add_argument("scenarios", nargs="*", help="scenario files or shipped names (default: the shipped ones "
                                                 "and the stress scenarios)")
    ap.add_argument("--markdown", action="store_true", help="one table row per scenario (docs/results.md's table)")
    args = ap.parse_args(argv)
    names = args.scenarios or [*list_tireforce_scenarios(),
                               *sorted(str(p) for p in (tireforce_scenario_dir() / STRESS_DIR).glob("*.toml"))]
    try:
        if args.markdown:
            print(markdown_header())
        for name in names:
            m = ablation(load_tireforce_scenario(name))
            print(markdown_row(m) if args.markdown else ablation_table(m) + "\n", flush=True)
    except ScenarioError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    return 0

