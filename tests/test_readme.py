"""The README's promises about itself: a quick start of exactly two commands, and a list of the optional
system packages that names every tool a test skips without (each one in .ci/apt-packages.txt, which CI
installs)."""
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()
APT = set((ROOT / ".ci" / "apt-packages.txt").read_text().split())
#: a tool a test looks for (shutil.which, or a skip reason) -> the Debian package that brings it
TOOLS = {"log2asc": "can-utils", "arm-none-eabi-gcc": "gcc-arm-none-eabi", "clang": "clang",
         "systemd-analyze": "systemd", "tmux": "tmux", "patchelf": "patchelf"}


def section(title: str) -> str:
    return README.split(title, 1)[1].split("\n#", 1)[0]


def test_the_quick_start_is_two_commands():
    block = re.search(r"```sh\n(.*?)```", section("## Quick start"), re.S).group(1)
    assert [line.split("#")[0].strip() for line in block.strip().splitlines()] == ["make demo", "make test"]


def test_the_optional_packages_are_listed_and_installed_by_ci():
    table = section("### Optional system packages")
    named = set(re.findall(r"^\| `([a-z0-9.+-]+)`", table, re.M)) | set(re.findall(r"`([a-z0-9.+-]+)`", table))
    wanted = {p for p in TOOLS.values()} | {"libnewlib-arm-none-eabi", "libclang-rt-14-dev", "kmod", "iproute2"}
    assert wanted <= named, wanted - named
    assert wanted <= APT, wanted - APT
    assert "vehest-can uml --fetch" in table  # the UML kernel is no package: how to get it


def test_every_tool_a_test_skips_without_is_listed():
    used = set()
    for path in (ROOT / "tests").rglob("*.py"):
        text = path.read_text()
        used |= {t for t in TOOLS if re.search(rf"which\(\"{re.escape(t)}\"\)|\"{re.escape(t)} not installed", text)}
    assert {"log2asc", "arm-none-eabi-gcc", "tmux", "systemd-analyze"} <= used  # what the tests look for today
    assert all(TOOLS[t] in section("### Optional system packages") for t in used)
