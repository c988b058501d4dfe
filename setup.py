"""Only what pyproject.toml cannot say yet: the cffi module and shipping the DBC files."""
import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

DATA = {"dbc": ("dbc", "*.dbc"), "scenarios": ("firmware_sim/scenarios", "*.toml"),
        "scenarios/chassis": ("firmware_sim/scenarios/chassis", "*.toml"),
        "scenarios/roll": ("firmware_sim/scenarios/roll", "*.toml"),
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


setup(
    cffi_modules=["c_core/vehest_build.py:ffibuilder", "c_core/roll/roll_build.py:ffibuilder",
                  "c_core/xcp/xcp_build.py:ffibuilder", "c_core/secoc/secoc_build.py:ffibuilder"],
    cmdclass={"build_py": BuildPyWithData},
    # The extension uses only the stable ABI (cffi's default): one wheel for CPython 3.11 and later.
    options={"bdist_wheel": {"py_limited_api": "cp311"}},
)
