"""Coverage-guided fuzzing of the ECU's RX + tick path (libFuzzer, ASan/UBSan/float-cast-overflow),
a short bounded run in the suite; the long run is `python tests/fuzz/run_fuzz.py --seconds 3600`."""
import os
import shutil
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent / "fuzz"))
import run_fuzz  # noqa: E402

pytestmark = pytest.mark.rebuild

CI = os.environ.get("CI", "").lower() in ("true", "1")


@pytest.fixture(scope="module")
def clang():
    if shutil.which("clang") is None:
        if CI:
            pytest.fail("clang is needed on CI (.ci/apt-packages.txt)", pytrace=False)
        pytest.skip("clang not installed (Debian: clang libclang-rt-14-dev)")


def _units(stderr: str) -> int:
    line = next(l for l in stderr.splitlines() if l.startswith("stat::number_of_executed_units"))
    return int(line.split(":")[-1])


def test_bounded_fuzz_run_finds_nothing(clang, tmp_path):
    r = run_fuzz.run(20, tmp_path)
    assert r.returncode == 0, r.stderr[-5000:]
    assert _units(r.stderr) > 1000
    assert not list(tmp_path.glob("crash-*"))


def test_the_fuzzer_reaches_an_accepted_chassis_frame_and_reports_it(clang, tmp_path):
    """Positive control: a planted abort behind an accepted CHS_Sensors frame and a filter step
    (-DVH_FUZZ_CANARY=1) is found from the seed corpus, so the harness does reach past E2E."""
    r = run_fuzz.run(60, tmp_path, defines=("-DVH_FUZZ_CANARY=1",))
    assert r.returncode != 0
    assert "deadly signal" in r.stderr or "ERROR: libFuzzer" in r.stderr
    assert list(tmp_path.glob("crash-*"))


@pytest.mark.parametrize("canary, what", [(2, "an XCP calibration write committed after seed & key"),
                                          (3, "a roll UKF step on frames that passed SecOC"),
                                          (4, "XCP seed & key locked out by wrong keys"),
                                          (5, "a safety-relevant XCP write refused outside the safe state")])
def test_the_fuzzer_reaches_past_xcp_seed_and_key_and_secoc(clang, tmp_path, canary, what):
    """Positive controls for the XCP and SecOC ops: a planted abort behind each is reached."""
    r = run_fuzz.run(30, tmp_path, defines=(f"-DVH_FUZZ_CANARY={canary}",))
    assert r.returncode != 0, what
    assert list(tmp_path.glob("crash-*")), what


def test_seed_corpus_is_made_of_real_frames(tmp_path):
    n = run_fuzz.seed_corpus(tmp_path)
    assert n >= 10 and all(p.stat().st_size > 80 for p in tmp_path.iterdir())
    names = {p.name.rstrip("0123456789_") for p in tmp_path.iterdir()}
    assert {"chassis", "protected", "roll", "roll_secoc", "xcp_cal", "xcp_daq"} <= names
