"""Only what pyproject.toml cannot say yet: the C extension and shipping the DBC files."""
import atexit
import importlib.util
import shutil
import sys
import tempfile
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext
from setuptools.command.build_py import build_py

DATA = {"dbc": ("dbc", "*.dbc"),
        **{f"scenarios/{s}": (f"firmware_sim/scenarios/{s}", "*.toml") for s in ("driveline", "camber", "tireforce", "roll")},
        "campaigns": ("firmware_sim/campaigns", "*.toml"), "cars": ("firmware_sim/cars", "*.toml"),
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
    """vehest_can._native: c_core/vehest_build.py generates the codec and compiles every source once
    with the strict flags, all in build_temp; then cffi's glue is written there and build_ext
    compiles it and links. Nothing is written into the source tree."""

    def run(self):
        sys.dont_write_bytecode = True  # no __pycache__ of the build scripts in c_core/
        spec = importlib.util.spec_from_file_location("vehest_build", "c_core/vehest_build.py")
        vehest_build = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(vehest_build)
        built = vehest_build.make_ffi(Path(self.build_temp).resolve()).distutils_extension(self.build_temp)
        (ext,) = self.extensions
        for attr in ("sources", "include_dirs", "extra_objects", "libraries", "extra_link_args"):
            setattr(ext, attr, getattr(built, attr))
        super().run()


#: pip builds in the checkout: setuptools' working folders (build/, the .egg-info) go to a temporary
#: directory instead, removed when the build ends, so an install writes nothing into the source tree
WORK = tempfile.mkdtemp(prefix="vehest-can-build-")
atexit.register(shutil.rmtree, WORK, ignore_errors=True)

setup(
    # sources and link arguments filled in by BuildExtCompilingC; only the stable ABI (cffi's default):
    # one wheel for CPython 3.11 and later
    ext_modules=[Extension("vehest_can._native", sources=[], py_limited_api=True)],
    cmdclass={"build_py": BuildPyWithData, "build_ext": BuildExtCompilingC},
    options={"build": {"build_base": f"{WORK}/build"}, "egg_info": {"egg_base": WORK},
             "bdist_wheel": {"py_limited_api": "cp311"}},
)
