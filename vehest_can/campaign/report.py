"""A campaign's report: per metric the spread (median, p95, worst and the worst run's
parameters), the pass rate of each acceptance line, the worst run as a scenario file of its
own, and plots (ECDF of each acceptance metric, the metric against its most influential parameter)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..plotting import Figures, pyplot
from ..sim.report import FAIL, LEGEND, PASS
from .spec import Campaign


def summarize(campaign: Campaign, table) -> dict:
    cols = table.column_names
    runs = np.asarray(table.column("run").to_pylist())
    errors = table.column("error").to_pylist()
    ok = np.array([e is None for e in errors])
    params = [c for c in cols if c.startswith("param.")]
    out: dict = {"campaign": campaign.name, "runs": len(runs), "failed": int((~ok).sum()),
                 "failures": [{"run": int(r), "error": e} for r, e in zip(runs, errors) if e is not None][:20],
                 "metrics": {}, "acceptance": []}
    for c in (c for c in cols if c.startswith("metric.")):
        v = np.asarray(table.column(c).to_pylist(), dtype=np.float64)
        good = ok & np.isfinite(v)
        no_value = int((ok & ~np.isfinite(v)).sum())  # runs that ran but gave no figure: shown, never hidden
        if not good.any():
            out["metrics"][c[7:]] = {"no_value": no_value}
            continue
        w = int(np.flatnonzero(good)[np.argmax(v[good])])
        out["metrics"][c[7:]] = {"no_value": no_value,
            "median": float(np.median(v[good])), "p95": float(np.percentile(v[good], 95)),
            "worst": float(v[w]), "worst_run": int(runs[w]),
            "worst_params": {p[6:]: table.column(p)[w].as_py() for p in params},
            "influence": _influence(v[good], {p[6:]: table.column(p).to_pylist() for p in params}, good),
        }
    for a in campaign.acceptance:
        col = f"metric.{a.metric}"
        v = (np.asarray(table.column(col).to_pylist(), dtype=np.float64) if col in cols
             else np.full(len(runs), np.nan))
        passed = np.array([ok[i] and a.passes(v[i]) for i in range(len(runs))])
        out["acceptance"].append({"line": a.line, "passed": int(passed.sum()), "of": len(runs),
                                  "rate": float(passed.mean()) if len(runs) else 0.0})
    return out


def _influence(v: np.ndarray, params: dict, good: np.ndarray) -> dict:
    """|Spearman rank correlation| of the metric with each numeric parameter."""
    out = {}
    for name, values in params.items():
        try:
            x = np.asarray(values, dtype=np.float64)[good]
        except (TypeError, ValueError):
            continue
        if len(x) > 2 and np.ptp(x) > 0 and np.ptp(v) > 0:
            rx, rv = np.argsort(np.argsort(x)), np.argsort(np.argsort(v))
            out[name] = float(abs(np.corrcoef(rx, rv)[0, 1]))
    return out


def table_text(summary: dict) -> str:
    lines = [f"== campaign {summary['campaign']}: {summary['runs']} runs, {summary['failed']} failed"]
    if summary["metrics"]:
        w = max(len(k) for k in summary["metrics"])
        lines.append(f"{'metric':<{w}}  {'median':>10} {'p95':>10} {'worst':>10}  worst run")
        for k, m in summary["metrics"].items():
            if "median" not in m:
                lines.append(f"{k:<{w}}  no value in any of the {m['no_value']} runs")
                continue
            lines.append(f"{k:<{w}}  {m['median']:10.4g} {m['p95']:10.4g} {m['worst']:10.4g}  #{m['worst_run']} "
                         + ", ".join(f"{p}={_fmt(v)}" for p, v in m["worst_params"].items())
                         + (f"  ({m['no_value']} runs without a value, not in these figures)" if m["no_value"] else ""))
    if summary["acceptance"]:
        lines.append("acceptance (pass rate over all runs; a failed run does not pass):")
        for a in summary["acceptance"]:
            verdict = PASS if a["passed"] == a["of"] else FAIL
            lines.append(f"  {verdict}  {a['line']}: {a['passed']} of {a['of']} ({100 * a['rate']:.1f} %)")
        lines.append(f"  {LEGEND}")
    for f in summary["failures"]:
        lines.append(f"  run #{f['run']} failed: {f['error']}")
    return "\n".join(lines)


def _fmt(v) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def write_run_scenario(campaign: Campaign, index: int, path: Path) -> Path:
    """Run ``index`` as a scenario file of its own (re-runs alone to the same metrics)."""
    import tomli_w

    doc, values = campaign.run_doc(index)
    head = (f"# Run {index} of campaign {campaign.name} ({campaign.path}), base {campaign.base_path}.\n"
            + "".join(f"# {k} = {_fmt(v)}\n" for k, v in values.items()))
    path.write_text(head + tomli_w.dumps(doc))
    return path


def plots(campaign: Campaign, table, summary: dict, out: Path) -> list[Path]:
    plt = pyplot()
    figs = Figures(out, dpi=100)
    ok = np.array([e is None for e in table.column("error").to_pylist()])
    names = [a.metric for a in campaign.acceptance] or list(summary["metrics"])[:6]
    for name in dict.fromkeys(names):
        col = f"metric.{name}"
        if col not in table.column_names or "median" not in summary["metrics"].get(name, {}):
            continue
        v = np.asarray(table.column(col).to_pylist(), dtype=np.float64)
        good = ok & np.isfinite(v)
        m = summary["metrics"][name]
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
        xs = np.sort(v[good])
        ax1.step(xs, np.arange(1, len(xs) + 1) / len(xs), where="post")
        for a in campaign.acceptance:
            if a.metric == name:
                for lim in (a.lo, a.hi):
                    if lim is not None:
                        ax1.axvline(lim, color="r", ls="--", label=f"acceptance {lim:g}")
        ax1.set(xlabel=name, ylabel="fraction of runs", title=f"ECDF ({good.sum()} runs)")
        ax1.grid(alpha=0.3)
        if ax1.get_legend_handles_labels()[0]:
            ax1.legend()
        if m["influence"]:
            p = max(m["influence"], key=m["influence"].get)
            x = np.asarray(table.column(f"param.{p}").to_pylist(), dtype=np.float64)
            ax2.plot(x[good], v[good], ".", alpha=0.6)
            ax2.set(xlabel=p, ylabel=name, title=f"vs the most influential parameter (|rho| {m['influence'][p]:.2f})")
            ax2.grid(alpha=0.3)
        else:
            ax2.axis("off")
        fig.suptitle(f"campaign {campaign.name}")
        figs.save(fig, f"{name.replace('/', '_')}.png")
    return figs.paths
