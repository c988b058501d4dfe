"""Each tyre's bound of SKFMEC-A (docs/tireforce.md, "Per-tyre bound"): the truth inside it on a held-out
run of each plant (not a design run its constants were chosen on), fixed point against double, and the
health DEGRADED when a bound exceeds the configured width."""
from __future__ import annotations

import numpy as np
import pytest

from vehest_can.errors import VehestError
from vehest_can.native import ffi, lib
from vehest_can.systems.tireforce import adaptive as A
from vehest_can.systems.tireforce import bound as B
from vehest_can.systems.tireforce import report as tr

SINE = next(r for r in B.RUNS if r.scenario.endswith("highway_sine_payload"))


def test_the_judged_runs_are_not_design_runs():
    assert SINE.role == "held-out"
    design = {r.scenario for r in B.RUNS if r.role == "design"}
    assert design == {"chassis_relation_70kph", "chassis_paper_mu_drop"}
    assert all(r.mass_delta_kg is not None for r in B.RUNS if r.role == "held-out" and r.scenario in design)


def check(sc):
    truth, dbl, fix = B.simulate(sc)
    peak = np.abs(np.asarray(truth["fy"])).max(0)
    assert fix.saturations == 0
    assert (np.abs(fix.bound - dbl.bound).max(0) / peak < 0.005).all()  # fixed vs double within 0.5 % of peak
    for run in (dbl, fix):
        c = B.coverage(truth, run)
        assert (c["coverage"] >= 95.0).all(), c
        assert (c["width"] < 40.0).all(), c  # not wider than a bound can be and still say something


def test_bound_covers_the_truth_on_a_held_out_run_veh14():
    check(B.scenario(SINE, "veh14", 6.0))


@pytest.mark.slow
def test_bound_covers_the_truth_on_a_held_out_run_commonroad_mb():
    check(B.scenario(SINE, "commonroad_mb"))


def test_degraded_when_a_bound_exceeds_the_configured_width():
    """bound_max = 1 N: every published step past INIT is DEGRADED (double and fixed point alike); with
    the default (2000 N) the same run is OK once the mass has converged."""
    truth, frames = B.scenario(SINE, "veh14", 3.0).run_with_frames(ffi, lib)
    dec = tr.decode_inputs(frames)
    u = dec.for_filter()
    for cls in (A.AdaptiveSkfmec, A.AdaptiveFixed):
        tight = cls(adaptive=A.AdaptiveConfig(bound_max=1.0)).run(u, dec.mask, dec.ride)
        default = cls().run(u, dec.mask, dec.ride)
        on = tight.health != A.H_INIT
        assert on.any() and (tight.health[on] == A.H_DEGRADED).all()
        assert (default.health == A.H_OK).any()
        assert np.array_equal(tight.fy, default.fy)  # the width limit changes the health, not the estimate


def test_bound_max_is_checked():
    with pytest.raises(VehestError):
        A.AdaptiveFixed(adaptive=A.AdaptiveConfig(bound_max=0.0))
