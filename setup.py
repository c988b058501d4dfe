"""Only what pyproject.toml cannot say yet: the cffi modules and shipping the DBC files."""
import importlib.util
import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_ext import build_ext
from setuptools.command.build_py import build_py

#: the cffi build scripts: each names its builder (make_ffi, which compiles nothing) and compiles its
#: objects (compile_objects) when build_ext runs, so a pip install compiles the C once
BUILD_SCRIPTS = ["c_core/vehest_build.py", "c_core/roll/roll_build.py", "c_core/xcp/xcp_build.py",
                 "c_core/secoc/secoc_build.py"]

DATA = {"dbc": ("dbc", "*.dbc"),
        **{f"scenarios/{s}": (f"firmware_sim/scenarios/{s}", "*.toml") for s in ("driveline", "camber", "tireforce", "roll")},
        "campaigns": ("firmware_sim/campaigns", "*.toml"),
        "examples/hil": ("examples/hil", "*.toml"), "examples/systemd": ("examples/systemd", "*")}


class BuildPyWithData(build_py):
    """Ship the DBC files and the scenarios inside the package, so an installed vehest-can finds them."""

    def run(self):
        super().run()
        for name, (src, pattern) in DATA.items():
            dest = Path(self.build_lib) / "vehest_can" / name
            dest.mkdir(parents=True, exist_ok=True)
            for f in sorted(p for p in Path(src).glob(pattern) if p.is_file()):
                shutil.copy2(f, dest / f.name)


class BuildExtCompilingC(build_ext):
    """Compile the build scripts' objects (with the strict flags, apart from cffi's glue), then the
    extensions that link them."""

    def run(self):
        for i, path in enumerate(BUILD_SCRIPTS):
            spec = importlib.util.spec_from_file_location(f"_vehest_build_script_{i}", path)
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
            module.compile_objects()
        super().run()


setup(
    cffi_modules=[f"{path}:make_ffi" for path in BUILD_SCRIPTS],
    cmdclass={"build_py": BuildPyWithData, "build_ext": BuildExtCompilingC},
    # The extension uses only the stable ABI (cffi's default): one wheel for CPython 3.11 and later.
    options={"bdist_wheel": {"py_limited_api": "cp311"}},
)
