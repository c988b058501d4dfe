"""One application shape, one descriptor per system: the ECU's list of applications is generated
from the descriptors (c_core/<system>/vh_<system>_app.def), and a fifth application registers by
its descriptor alone (a toy here, in tests/systems/toy_app/), with no edit to a shared file."""
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "c_core"))
import ecu_gen  # noqa: E402
import vehest_build  # noqa: E402
from cbuild import cdef_of  # noqa: E402

TOY = Path(__file__).parent / "toy_app"
ECU_DIR = ROOT / "c_core" / "ecu"


def test_the_committed_app_list_and_xcp_description_are_the_descriptors():
    """c_core/ecu/vh_ecu_apps.{h,inc} and vehest_can/xcp/ecu.toml are c_core/ecu_gen.py's output, unedited."""
    for name, text in ecu_gen.generate().items():
        path = ecu_gen.TOML if name == "ecu.toml" else ECU_DIR / name
        assert path.read_text() == text, f"{path}: run python c_core/ecu_gen.py"
    assert [m for _, m, _ in ecu_gen.descriptors()] == ["drv", "camber", "tf", "roll"]


def test_the_generator_is_standalone_and_every_shipped_file_is_current(tmp_path):
    """c_core/ecu_gen.py --check (app list, XCP description, limit table, A2L, XCP DBC) runs
    without importing the vehest_can package, and finds nothing to regenerate."""
    code = "\n".join([
        "import runpy, sys",
        "sys.argv = ['ecu_gen.py', '--check']",
        "code = 0",
        "try:",
        f"    runpy.run_path({str(ROOT / 'c_core' / 'ecu_gen.py')!r}, run_name='__main__')",
        "except SystemExit as e:",
        "    code = e.code",
        "assert not [m for m in sys.modules if m.split('.')[0] == 'vehest_can'], 'imported vehest_can'",
        "sys.exit(code)"])
    run = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr


def test_the_scheduler_names_no_system():
    """No system in c_core/ecu outside the generated app list."""
    import re

    names = re.compile(r"driveline|tireforce|camber|roll|skf|dkf|tfa", re.I)
    hits = [f"{p.name}:{i}" for p in sorted(ECU_DIR.glob("*.[ch]")) if p.name != "vh_ecu_apps.h"
            for i, line in enumerate(p.read_text().splitlines(), 1) if names.search(line)]
    assert not hits


def _headers(gen: Path, ecu: Path) -> list[Path]:
    """The firmware's public headers with the toy's app list (in `ecu`), each after those it includes."""
    vehest_build.dbcgen.generate_all(gen)
    headers = [h for h in vehest_build.public_headers(gen) if h.parent != vehest_build.SIM_INCLUDE_DIR]
    i = [h.name for h in headers].index("vh_ecu_apps.h")
    headers[i:i + 1] = [TOY / "vh_toy_app.h", ecu / "vh_ecu_apps.h"]
    return headers


def _ffi(gen: Path, ecu: Path):
    """The declarations of the firmware built with the toy (its app list in `ecu`), parsed only: the
    layout the XCP description is laid out by, as c_core/ecu_gen.py does."""
    from cffi import FFI

    ffi = FFI()
    ffi.cdef("\n".join([p.read_text() for p in sorted(gen.glob("*.cdef"))] + [cdef_of(h) for h in _headers(gen, ecu)]))
    return ffi


def _toy_firmware(tmp_path: Path):
    """(gen, ecu folder, sources, include dirs) of the firmware with the toy application: the
    scheduler's folder copied beside, its app list and XCP description regenerated with the toy's
    descriptor, the slave's limit table laid out by them. Returns the description too."""
    from vehest_can.xcp import ecu_desc

    gen, ecu, toml = tmp_path / "generated", tmp_path / "ecu", tmp_path / "ecu.toml"
    shutil.copytree(ECU_DIR, ecu, ignore=shutil.ignore_patterns("vh_ecu_apps.*", "*.toml"))
    subprocess.run([sys.executable, str(ROOT / "c_core" / "ecu_gen.py"), "--out", str(ecu), "--toml", str(toml),
                    "--def", str(TOY / "vh_toy_app.def")], check=True)
    desc = ecu_desc.describe(_ffi(gen, ecu), toml)
    (ecu / "vh_ecu_xcp_table.inc").write_text(ecu_desc.c_table(desc))  # the slave's table with the toy's items
    fw = [s for s in vehest_build.firmware_sources(gen)
          if s.parent != vehest_build.SIM_SRC_DIR and s.parent != ECU_DIR]
    sources = [*fw, *sorted(ecu.glob("*.c")), TOY / "vh_toy_app.c"]
    includes = [ecu, TOY, *(d for d in vehest_build.firmware_include_dirs(gen) if d != ECU_DIR)]
    return gen, ecu, sources, includes, desc


@pytest.mark.rebuild  # compiles a firmware of its own
@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_a_toy_fifth_application_is_received_scheduled_sends_and_is_measured_over_xcp(tmp_path):
    """The toy's descriptor (one RX ID, a runnable every 10 ticks, a TX frame every 20, two
    measurements and a characteristic) added to the generator's input: the ECU built from it
    dispatches the toy's frames to it (not counted as unknown), runs its runnable at its rate, sends
    its frame, and its XCP slave uploads the toy's counter from the address the description gives."""
    gen, ecu, sources, includes, desc = _toy_firmware(tmp_path)
    assert "X(toy)" in (ecu / "vh_ecu_apps.h").read_text()
    assert {"app.toy.runs", "app.toy.sum", "app.drv.dkf[0].x[2]"} <= {it.name for it in desc.measurements}
    assert desc.item("cal.app.toy.gain").safety_class == "tuning"
    sources.append(TOY / "toy_main.c")
    exe = tmp_path / "toy"
    build = subprocess.run(["cc", *vehest_build.STRICT_FLAGS, "-O1", *(f"-I{d}" for d in includes),
                            *map(str, sources), *vehest_build.LINK_FLAGS, "-o", str(exe)],
                           capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    run = subprocess.run([str(exe), hex(desc.item("app.toy.runs").address)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stdout + run.stderr
    out = run.stdout.split()
    got = {k: int(v) for k, v in zip(out[::2], out[1::2])}
    # runs at ticks 0, 10, .. 90 on that tick's frame (first byte = tick), gain 3, sent at 0, 20, .. 80;
    # the XCP CONNECT's tick is 100: an 11th run, on the frame of tick 99
    assert got == {"xcp_runs": 11, "runs_now": 11, "apps": 5, "frames": 100, "runs": 11,
                   "sum": 3 * (sum(range(0, 100, 10)) + 99), "gain": 3, "unknown_id": 0, "toy_tx": 5,
                   "toy_tx_ticks": sum(range(0, 100, 20)), "last_sum": 3 * sum(range(0, 90, 10))}


@pytest.mark.rebuild  # compiles a firmware of its own
@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_a_toy_system_is_configured_and_reported_by_the_python_ecu(tmp_path, monkeypatch):
    """The same firmware as a cffi module behind vehest_can's Ecu, and a toy System registered in
    Python (its part of the configuration, its estimator): the ECU view takes both with no edit to
    ecu.py; the four shipped systems are configured and reported beside it."""
    import can
    from cffi import FFI

    from vehest_can.systems import EcuEstimator, Registration, register, unregister
    from vehest_can.systems import ecu as ecu_mod

    gen, ecu, sources, includes, _ = _toy_firmware(tmp_path)
    objects = vehest_build.compile_strict(sources, includes, tmp_path / "obj", ["-O1"])
    ffi = FFI()
    ffi.cdef("\n".join([p.read_text() for p in sorted(gen.glob("*.cdef"))] + [cdef_of(h) for h in _headers(gen, ecu)]))
    glue = [h.name for h in _headers(gen, ecu)] + [p.name for p in sorted(gen.glob("vh_*.h"))
                                                   if "_meta" not in p.name and p.name != "vh_secoc_table.h"]
    ffi.set_source("_vehest_toy", "\n".join(f'#include "{h}"' for h in dict.fromkeys(glue)),
                   include_dirs=[str(d) for d in includes], extra_objects=objects, libraries=["m"],
                   extra_link_args=vehest_build.LINK_FLAGS[1:])
    sys.path.insert(0, str(tmp_path))
    try:
        ffi.compile(tmpdir=str(tmp_path))
        import _vehest_toy as toy
    finally:
        sys.path.remove(str(tmp_path))
    monkeypatch.setattr(ecu_mod, "ffi", toy.ffi)
    monkeypatch.setattr(ecu_mod, "lib", toy.lib)

    class ToyApp(Registration):
        name = "toyapp"
        estimators = (EcuEstimator("toy", "TOY_In", lambda c: 1 if c.app.toy.runs else 0,
                                   lambda c: bool(c.app.toy.frames)),)

        def configure_ecu(self, app, part):
            app.toy.gain = 3 if part is None else part

    system = ToyApp()
    register(system)
    try:
        e = ecu_mod.Ecu(ecu_mod.EcuConfig(systems={"toyapp": 5}))
        assert e.c.app.toy.cfg.gain == 5 and e.c.app.drv.cfg.we_min == 40.0
        assert e.not_heard()[-1] == "toy" and e.health()["toy"] == "INIT"
        sent = []
        for k in range(100):
            e.rx(can.Message(arbitration_id=0x555, data=bytes([k, 0, 0, 0, 0, 0, 0, 0]), is_extended_id=False))
            sent += [bytes(m.data[:4]) for m in e.step() if m.arbitration_id == 0x556]
        assert e.heard()["TOY_In"] and "toy" not in e.not_heard() and e.health()["toy"] == "OK"
        assert len(sent) == 5 and int.from_bytes(sent[-1], "little") == 5 * sum(range(0, 90, 10))
        assert e.counters()["unknown_id"] == 0 and set(e.health()) >= {"dkf_t", "skfmec_q", "roll_ukf", "toy"}
    finally:
        unregister(system)
