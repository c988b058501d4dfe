"""pytest glue: hypothesis settings for a slow machine; the user-mode-Linux harness
(vehest_can.tools.uml) as the ``uml`` fixture."""

import os

import pytest
from hypothesis import HealthCheck, settings

from vehest_can.tools import uml as _uml

# the property tests are about correctness, not speed: no deadline, no health check that trips when
# the machine is loaded (each test's own @settings still sets its number of examples)
settings.register_profile("vehest", deadline=None,
                          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
settings.load_profile("vehest")


@pytest.fixture(scope="session")
def uml(tmp_path_factory):
    """``vehest_can.tools.uml``, once one probe boot has run a command in the guest.

    Skips with the reason when UML, its CAN modules or can-utils are missing, or the probe boot
    fails; with ``CI=true`` in the environment it fails instead, because CI must run these tests.
    """
    ok, reason = _uml.available()
    if ok:
        try:
            probe = _uml.run("true", timeout=120, workdir=tmp_path_factory.mktemp("uml-probe"))
        except _uml.UmlError as exc:
            ok, reason = False, f"probe boot failed: {exc.summary} (console: {exc.workdir})"
        else:
            if probe.returncode != 0:
                ok, reason = False, f"probe `true` exited {probe.returncode}: {probe.stderr}"
    if not ok:
        message = f"user-mode Linux unavailable: {reason}"
        if os.environ.get("CI", "").lower() in ("true", "1"):
            pytest.fail(f"{message}\n(CI=true: the UML tests must run; see docs/uml.md)",
                        pytrace=False)
        pytest.skip(message)
    return _uml
