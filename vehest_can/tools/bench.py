"""``vehest-can bench``: speed figures, measured side by side in one process (the verb's
description, vehest_can.cli.bench, says which and their targets)."""
from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ..bus.frames import TICK_S
from ..native import ffi, lib
from ..systems.driveline import reference as dkf_ref
from ..systems.driveline.api import DkfConfig, DrivelineKF
from ..systems.ecu import Ecu

ROOT = Path(__file__).resolve().parents[2]  # the source checkout: c_core/ is built from here


def _median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def _data(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    wo = 200 + 2 * np.arange(n) * TICK_S
    z = np.c_[wo + rng.normal(0, 5, n), 0.255 * wo + rng.normal(0, 2, n), 1500 + rng.normal(0, 7, n)]
    return np.full(n, 170.0), z


def _build_run(sources, include_dirs, args=(), generated=None) -> str | None:
    """Compile c_core/bench sources with the extension's compiler and flags, run the program and give its
    output; None without a compiler. `generated(dir)`: writes the generated sources first and gives
    their list."""
    sys.path.insert(0, str(ROOT / "c_core"))
    import cbuild
    import vehest_build

    cc = cbuild.cc()
    if shutil.which(cc[0]) is None:
        return None
    with tempfile.TemporaryDirectory() as tmp:
        srcs = [*(generated(Path(tmp) / "generated") if generated else []), *sources]
        exe = Path(tmp) / "bench"
        subprocess.run([*cc, *vehest_build.STRICT_FLAGS, *vehest_build.OPT_FLAGS,
                        *(f"-I{d}" for d in include_dirs(Path(tmp) / "generated")), *map(str, srcs),
                        *vehest_build.LINK_FLAGS, "-o", str(exe)], check=True, capture_output=True, text=True)
        return subprocess.run([str(exe), *args], check=True, capture_output=True, text=True).stdout


def c_loop(bench: str = "vh_bench.c") -> dict[str, tuple[float, float]] | None:
    """Build c_core/bench/<bench> with the extension's flags and run it: {name: (median_ns, p99_ns)}."""
    src = ROOT / "c_core" / "bench" / bench
    if not src.exists():
        return None
    sys.path.insert(0, str(ROOT / "c_core"))
    import vehest_build

    out = _build_run([src], vehest_build.bench_include_dirs, generated=vehest_build.firmware_sources)
    if out is None:
        return None
    rows = {}
    for line in out.splitlines():
        name, _, med, p99 = line.split()
        rows[name] = (float(med), float(p99))
    return rows


def run(quick: bool = False) -> dict:
    n = 2000 if quick else 20000
    repeats = 3 if quick else 7
    u, z = _data(n)
    cfg = DkfConfig.default("speeds+torque")
    res: dict = {"steps": n}

    kf = DrivelineKF(cfg)
    def array_api():
        kf.reset()
        kf.run(u, z)

    res["array_api_ns"] = _median_time(array_api, repeats) / n * 1e9

    f = ffi.new("vh_dkf_t *")
    lib.vh_dkf_init(f, cfg.to_c())
    zc = ffi.new("double[3]")
    step = lib.vh_dkf_step

    def single_calls():
        for i in range(n):
            zc[0], zc[1], zc[2] = z[i]
            step(f, 170.0, zc, 15)

    res["single_cffi_ns"] = _median_time(single_calls, repeats) / n * 1e9
    m = min(n, 4000)
    res["numpy_ref_ns"] = _median_time(lambda: dkf_ref.run(cfg, u[:m], z[:m]), max(1, repeats // 2)) / m * 1e9
    try:
        from filterpy.kalman import KalmanFilter
    except ImportError:
        res["filterpy_ns"] = None
    else:
        a, b = dkf_ref.model(cfg)
        ad, bd = dkf_ref.discretise(a, b, cfg.ts, cfg.disc)

        def filterpy_run():
            kf2 = KalmanFilter(dim_x=4, dim_z=3, dim_u=1)
            kf2.F, kf2.B = ad, bd.reshape(4, 1)
            kf2.H = np.eye(4)[:3]
            kf2.Q, kf2.R, kf2.P = np.diag(cfg.q), np.diag(cfg.r), np.diag(cfg.p0)
            kf2.x = np.array([z[0, 0], z[0, 1], z[0, 2], 0.0])
            for i in range(m):
                kf2.predict(u=np.array([[u[i]]]))
                kf2.update(z[i])

        res["filterpy_ns"] = _median_time(filterpy_run, max(1, repeats // 2)) / m * 1e9
    res["c_loop"] = c_loop()
    res["ecu_xcp"] = c_loop("vh_bench_ecu_xcp.c")  # the ECU tick with the XCP slave beside without
    res["ecu_secoc"] = c_loop("vh_bench_ecu_secoc.c")  # the ECU tick with SecOC on beside off
    res["secoc"] = c_loop("bench_secoc.c")  # CMAC, protect and verify per frame
    res["tireforce"] = tireforce(c_samples=4000 if quick else 40000, ref_steps=100 if quick else 400,
                                 repeats=1 if quick else 3)
    res["chassis_plant"] = chassis_plant(seconds=1.0 if quick else 10.0, repeats=3 if quick else 9)
    res["roll"] = roll(steps=400 if quick else 1200, ref_steps=20 if quick else 60, repeats=3 if quick else 7)
    res["startup_s"] = startup(3 if quick else 10)
    return res


def roll(steps: int = 1200, ref_steps: int = 60, repeats: int = 7) -> dict:
    """Seed-003 roll UKF step, the paper's variant (n = 16, 33 sigma points) and the robust one (n = 21,
    43): the C float32 and double builds through the array API (one call per run) against filterpy's
    UnscentedKalmanFilter on the paper's model and sigma points (ref.filterpy_ukf); the robust model as
    the numpy reference UKF and as its EKF (same model, Q, R, P0), both numpy, for the cost of one
    against the other; on the paper's 72 km/h case at the ECU's 5 ms step."""
    from ..systems.roll import api as rn
    from ..systems.roll import evaluate as ev
    from ..systems.roll import reference as ref

    prm = rn.default_params()
    prm.dt = 0.005
    truth = ev.run_plant(ev.paper_case(72.0, duration_s=max(1.0, steps * prm.dt + 0.01)))
    u, z, _ = ev.synthesise(truth, decim=10, prm=prm)
    u, z = u[:steps], z[:steps]
    out: dict = {"steps": len(u)}
    m = min(ref_steps, len(u))
    for variant, tag in (("paper", ""), ("robust", "robust_")):
        prm.variant = rn.VARIANTS[variant]
        for prec in ("f32", "f64"):
            k = rn.Ukf(prm, prec)

            def run_c(k=k):
                k.reset()
                k.run(u, z)

            out[f"c_{tag}{prec}_ns"] = _median_time(run_c, repeats) / len(u) * 1e9
    p = rn.params_dict(prm)  # the robust variant's
    for name, cls in (("ref_robust_ukf_ns", ref.RefUkf), ("ref_robust_ekf_ns", ref.RefEkf)):
        out[name] = _median_time(lambda cls=cls: cls(p).run(u[:m], z[:m]), max(1, repeats // 3)) / m * 1e9
    prm.variant = rn.VARIANTS["paper"]
    try:
        p = rn.params_dict(prm)
        ref.filterpy_ukf(p)
    except ImportError:
        out["filterpy_ns"] = None
        return out

    def run_fp():
        f = ref.filterpy_ukf(p)
        for i in range(m):
            ref.filterpy_step(f, u[i], z[i])

    out["filterpy_ns"] = _median_time(run_fp, max(1, repeats // 3)) / m * 1e9
    return out


def skf_inputs(n: int):
    """The inputs of c_core/bench/vh_bench_skf.c (0.5 Hz sine steer at 70 km/h, its LCG noise), as tireforce.Inputs."""
    from ..systems.tireforce.api import Inputs

    t = np.arange(n) * 5e-4
    vx = 19.44
    lcg, noise = 12345, np.empty(n)
    for i in range(n):
        lcg = (lcg * 1103515245 + 12345) & 0xFFFFFFFF
        noise[i] = ((lcg >> 16) / 65536.0 - 0.5) * 0.02
    delta = 0.035 * np.sin(2.0 * 3.14159265358979 * 0.5 * t)
    r = vx * delta / 2.693 + noise
    return Inputs(ax=noise.copy(), ay=vx * r + noise, r=r, p=0.01 * np.cos(2.0 * 3.14159265358979 * 0.5 * t) + noise,
                  delta=delta, omega=np.repeat((vx / 0.305 + noise)[:, None], 4, axis=1), torque=np.full((n, 4), 10.0))


def tireforce(c_samples: int = 40000, ref_steps: int = 400, repeats: int = 3) -> dict:
    """Seed-000 estimators: C-loop steps (bench_c_loop: skfmec_fixed_step, skfmec_double_step,
    ekf_double_step; {name: (median_ns, p99_ns)}, None without a compiler) and the numpy reference
    SKFMEC step (skf_ref.run, median ns/step over `ref_steps` steps of the same inputs)."""
    from ..systems.tireforce import reference as skf_ref
    from ..systems.tireforce.api import SKFMEC, SkfConfig

    cfg = SkfConfig.default(SKFMEC)
    inp = skf_inputs(ref_steps)
    ref_ns = _median_time(lambda: skf_ref.run(cfg, inp.ax, inp.ay, inp.r, inp.p, inp.delta, inp.omega, inp.torque),
                          repeats) / ref_steps * 1e9
    return {"c_loop": bench_c_loop(samples=c_samples), "numpy_ref_ns": ref_ns, "ref_steps": ref_steps}


def chassis_plant(seconds: float = 10.0, repeats: int = 9) -> dict[str, float]:
    """The 14-DOF chassis plant alone on the tyre-force paper's manoeuvre (vehest_can.sim.veh14.bench)."""
    from ..sim.veh14 import bench
    from ..systems.tireforce.scenario import load_tireforce_scenario

    return bench(load_tireforce_scenario("chassis_paper_mu_drop"), seconds=seconds, repeats=repeats)


#: command lines timed from a new process: the console script's help and three verbs', beside the
#: interpreter alone and cantools' command line (baselines of the same run)
STARTUP = (("vehest-can --help", ["-m", "vehest_can.cli", "--help"]),
           ("vehest-can demo --help", ["-m", "vehest_can.cli", "demo", "--help"]),
           ("vehest-can replay --help", ["-m", "vehest_can.cli", "replay", "--help"]),
           ("vehest-can sim --help", ["-m", "vehest_can.cli", "sim", "--help"]),
           ("baseline: python -c pass", ["-c", "pass"]),
           ("baseline: cantools --help", ["-m", "cantools", "--help"]))


def startup(repeats: int = 10) -> dict[str, float]:
    """Median wall time [s] of each STARTUP command line in a new process (target <= 0.3 s)."""
    out = {}
    for name, argv in STARTUP:
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, *argv], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
            times.append(time.perf_counter() - t0)
        out[name] = float(np.median(times))
    return out


def lockstep_factors(car_factory, repeats: int = 3) -> tuple[float, float]:
    """Median real-time factors of a car alone (plant and nodes in one C call, frames dropped) and of
    its in-process lockstep with the ECU (vehest_can.sim.session.run_inprocess), in the same run."""
    from ..native import lib
    from ..sim.session import run_inprocess

    alone, lockstep = [], []
    for _ in range(repeats):
        car = car_factory()
        car.reset()
        t0 = time.perf_counter()
        lib.vh_car_run(car.c, 0, car.n)
        alone.append(car.n * TICK_S / (time.perf_counter() - t0))
        lockstep.append(run_inprocess(car_factory(), Ecu()).stats["realtime_factor"])
    return float(np.median(alone)), float(np.median(lockstep))


def _tick_rows(res: dict, rows: tuple[tuple[str, str], ...], feature: str) -> list[str]:
    """Tick medians and p99 of one C-loop run, each against the first row (the feature off)."""
    base = res[rows[0][0]][0]
    return [f"{name:<44}{res[key][0] / 1000:>9.2f} µs/tick   p99 {res[key][1] / 1000:.2f} µs, "
            f"{res[key][0] / base:.2f}x the tick without {feature}" for key, name in rows]


#: the C-loop runs that time the ECU tick with a feature off, then on: (result key, feature, rows against
#: the first, (the run's counts: key, label, what its two numbers count))
_FEATURE_RUNS = (
    ("ecu_xcp", "XCP", (("ecu_tick_no_xcp", "ECU tick, XCP off (same run)"),
                        ("ecu_tick_xcp_idle", "ECU tick, XCP on, connected, idle"),
                        ("ecu_tick_xcp_daq", "ECU tick, XCP 18-signal DAQ at 1 ms")),
     # "xcp_daq_dtos ticks dtos overruns": the DAQ ran within its budget
     ("xcp_daq_dtos", "  XCP DAQ in that run", "DTOs", "samples dropped")),
    ("ecu_secoc", "SecOC", (("ecu_tick_secoc_off", "ECU tick, every system, SecOC off (same run)"),
                            ("ecu_tick_secoc_on", "ECU tick, every system, SecOC on"),
                            ("ecu_tick_secoc_forged", "  on + a forged frame every tick")),
     # "secoc_counts ticks accepted rejected"
     ("secoc_counts", "  SecOC in that run", "frames verified", "rejected")),
)


def table(res: dict, lockstep: dict[str, tuple[float, float]] | None = None) -> str:
    lines = [f"{'benchmark':<44}{'median':>14}{'vs filterpy':>13}"]
    fp = res.get("filterpy_ns")

    def row(name, ns, unit="ns/step"):
        ratio = f"{fp / ns:>11.0f}x" if fp and ns else f"{'-':>12}"
        lines.append(f"{name:<44}{ns:>9.0f} {unit}{ratio}")

    c = res.get("c_loop") or {}
    if "dkf_step" in c:
        row("KF step, C loop", c["dkf_step"][0])
    row("KF step, Python array API (one call/run)", res["array_api_ns"])
    row("KF step, one cffi call per step", res["single_cffi_ns"])
    row("KF step, numpy reference", res["numpy_ref_ns"])
    if fp:
        row("KF step, filterpy KalmanFilter", fp)
    if "ecu_tick" in c:
        lines.append(f"{'ECU tick (rx+unpack+checks+2 KF+pack), C loop':<44}{c['ecu_tick'][0] / 1000:>9.2f} µs/tick"
                     f"   p99 {c['ecu_tick'][1] / 1000:.2f} µs (target <= 5 µs)")
    if "ecu_tick_chassis" in c:
        lines.append(f"{'ECU tick + CHS frame + SKFMEC, SKFMEC-A':<44}{c['ecu_tick_chassis'][0] / 1000:>9.2f} µs/tick"
                     f"   p99 {c['ecu_tick_chassis'][1] / 1000:.2f} µs (target <= 10 µs)")
    for run, feature, rows, (count_key, label, first, second) in _FEATURE_RUNS:
        got = res.get(run) or {}
        if rows[0][0] in got:
            lines += _tick_rows(got, rows, feature)
            if count_key in got:
                lines.append(f"{label:<44}{got[count_key][0]:>9.0f} {first}, {got[count_key][1]:.0f} {second}")
    for key, value in (res.get("secoc") or {}).items():
        if key != "clock":
            lines.append(f"{'SecOC ' + key:<44}{value[0]:>9.0f} ns   p99 {value[1]:.0f} ns")
    tf = res.get("tireforce") or {}
    tc, ref = tf.get("c_loop") or {}, tf.get("numpy_ref_ns")
    for key, name in (("skfmec_fixed_step", "SKFMEC fixed-point step, C loop"),
                      ("skfmec_a_fixed_step", "SKFMEC-A fixed-point step, C loop"),
                      ("skfmec_double_step", "SKFMEC double step, C loop"), ("ekf_double_step", "EKF double step, C loop")):
        if key in tc:
            vs = f"   p99 {tc[key][1]:.0f} ns, {ref / tc[key][0]:.0f}x numpy ref" if ref else ""
            lines.append(f"{name:<44}{tc[key][0]:>9.0f} ns/step{vs}")
    if ref:
        lines.append(f"{'SKFMEC step, numpy reference (skf_ref)':<44}{ref / 1000:>9.0f} µs/step")
    cp = res.get("chassis_plant")
    if cp:
        lines.append(f"{'14-DOF chassis plant alone, C (vh_v14_run)':<44}{cp['us_per_step_cpu_best']:>9.2f} µs/step"
                     f"   = {cp['x_real_time_cpu_best']:.0f}x real time, best (median {cp['x_real_time_cpu_median']:.0f}x;"
                     f" target >= 200x)")
    if "car_tick" in c:
        lines.append(f"{'car tick (plant + sensor node), C loop':<44}{c['car_tick'][0] / 1000:>9.2f} µs/tick"
                     f"   = {500 / (c['car_tick'][0] / 1000):.0f}x real time")
    rl = res.get("roll") or {}
    if rl:
        fpu = rl.get("filterpy_ns")
        for key, name in (("c_f32_ns", "roll UKF step, C float32 (array API)"),
                          ("c_f64_ns", "roll UKF step, C double (array API)"),
                          ("c_robust_f32_ns", "roll robust UKF step, C float32"),
                          ("c_robust_f64_ns", "roll robust UKF step, C double")):
            if key in rl:
                vs = f"   {fpu / rl[key]:.0f}x filterpy UKF (target >= 100x)" if fpu else ""
                lines.append(f"{name:<44}{rl[key] / 1000:>9.2f} µs/step{vs}")
        if fpu:
            lines.append(f"{'roll UKF step, filterpy UnscentedKalmanFilter':<44}{fpu / 1000:>9.0f} µs/step")
        lines.append(f"roll UKF float32 / double step time: {rl['c_f32_ns'] / rl['c_f64_ns']:.2f}")
        if "ref_robust_ekf_ns" in rl:
            lines.append(f"{'roll robust model, numpy UKF step':<44}{rl['ref_robust_ukf_ns'] / 1000:>9.0f} µs/step")
            lines.append(f"{'roll robust model, numpy EKF step (FD Jac.)':<44}{rl['ref_robust_ekf_ns'] / 1000:>9.0f} µs/step"
                         f"   {rl['ref_robust_ukf_ns'] / rl['ref_robust_ekf_ns']:.2f}x the UKF's speed")
    if "ecu_tick_all" in c:
        mx = f", longest {c['ecu_all_roll'][1] / 1000:.1f} µs (target <= 100 µs)" if "ecu_all_roll" in c else ""
        lines.append(f"{'ECU tick, every system (+ roll UKF + SMC)':<44}{c['ecu_tick_all'][0] / 1000:>9.2f} µs/tick"
                     f"   p99 {c['ecu_tick_all'][1] / 1000:.2f} µs{mx} (target median <= 15 µs)")
    for name, secs in res.get("startup_s", {}).items():
        target = "" if name.startswith("baseline") else " (target <= 0.3 s)"
        lines.append(f"{'start-up ' + name:<44}{secs * 1000:>9.0f} ms median{target}")
    for name, (alone, factor) in (lockstep or {}).items():
        # CommonRoad's multi-body plant is a Python package compiled at run time: its target is the car's
        mb = name.endswith("@commonroad_mb")
        lines.append(f"{'in-process lockstep ' + name:<44}{factor:>9.0f}x real time"
                     + ("" if mb else " (target >= 100x)") + f"; the car alone {alone:.0f}x"
                     + (" (target >= 10x)" if mb else ""))
    if fp:
        lines.append(f"array API vs filterpy: {fp / res['array_api_ns']:.0f}x faster (target >= 100x)")
    if ref and "skfmec_fixed_step" in tc and "skfmec_double_step" in tc:
        lines.append(f"fixed-point C step is {ref / tc['skfmec_fixed_step'][0]:.0f}x, double C step "
                     f"{ref / tc['skfmec_double_step'][0]:.0f}x faster than the numpy reference step")
    if "ecu_tick" in c and "ecu_tick_chassis" in c:
        lines.append(f"chassis side of the ECU tick: +{(c['ecu_tick_chassis'][0] - c['ecu_tick'][0]) / 1000:.2f} µs median")
    return "\n".join(lines)


def bench_c_loop(samples: int = 40000) -> dict[str, tuple[float, float]] | None:
    """Build and run ``c_core/bench/vh_bench_skf.c`` with the extension's flags.

    Returns {name: (median_ns, p99_ns)} for ``skfmec_double_step``, ``ekf_double_step``,
    ``skfmec_fixed_step`` and ``skfmec_a_fixed_step`` (one step timed call by call in a C loop), and
    {name: (value, 0)} for the fixed-point filters' saturation counts and final-state checksums
    (``skfmec_fixed_checksum``, ...), or None without a compiler.
    """
    src = ROOT / "c_core" / "bench" / "vh_bench_skf.c"
    if not src.exists():
        return None
    sys.path.insert(0, str(ROOT / "c_core"))
    import vehest_build

    sources = [src] + [vehest_build.firmware_path(f) for f in ("vh_skf.c", "vh_skfq.c", "vh_skfq_host.c",
                                                                     "vh_tfa.c", "vh_tfa_host.c", "vh_fix.c")]
    out = _build_run(sources, lambda _gen: vehest_build.FIRMWARE_DIRS, args=(str(samples),))
    if out is None:
        return None
    rows = {}
    for line in out.splitlines():
        name, count, med, p99 = line.split()
        # the saturation counts and state checksums ("name value 0 0") keep their value
        rows[name] = (float(count), 0.0) if name.endswith(("_saturations", "_checksum")) else (float(med), float(p99))
    return rows
