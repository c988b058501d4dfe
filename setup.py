"""Only what pyproject.toml cannot say yet: the cffi module and shipping the DBC files."""
import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py


class BuildPyWithDbc(build_py):
    """Ship dbc/*.dbc inside the package, so an installed vehest-can finds its matrix."""

    def run(self):
        super().run()
        dest = Path(self.build_lib) / "vehest_can" / "dbc"
        dest.mkdir(parents=True, exist_ok=True)
        for dbc in sorted(Path("dbc").glob("*.dbc")):
            shutil.copy2(dbc, dest / dbc.name)


setup(
    cffi_modules=["c_core/vehest_build.py:ffibuilder"],
    cmdclass={"build_py": BuildPyWithDbc},
)
