"""Python configuration classes derived from the C structs (vehest_can.native.config_class), not
hand copies: the same fields in the same order, the C defaults function's values, a lossless round trip,
and what C could not hold refused as a ConfigError."""
from __future__ import annotations

import dataclasses

import pytest

from vehest_can.errors import ConfigError
from vehest_can.native import config_class, ffi, lib
from vehest_can.systems.camber.api import CalibrationLimits, MeasureConfig
from vehest_can.systems.driveline.api import DkfConfig
from vehest_can.systems.tireforce.api import SkfConfig

DERIVED = [(DkfConfig, lambda c: lib.vh_dkf_config_default(c, lib.VH_DKF_SPEEDS_TORQUE)),
           (CalibrationLimits, lib.vh_camber_cal_limits_default),
           (MeasureConfig, lib.vh_camber_config_default),
           (SkfConfig, lambda c: lib.vh_skf_config_default(c, lib.VH_SKF_SKFMEC))]


@pytest.mark.parametrize("cls, fill", DERIVED, ids=[c.__name__ for c, _ in DERIVED])
def test_fields_and_defaults_are_the_c_structs(cls, fill):
    c = ffi.new(f"{cls.C_TYPE} *")
    fill(c)
    names = [f.name for f in dataclasses.fields(cls)]
    assert names == [name for name, _ in ffi.typeof(cls.C_TYPE).fields]
    default = cls()
    back = cls.to_c(default)
    assert bytes(ffi.buffer(back)) == bytes(ffi.buffer(c))  # every byte the C defaults function wrote
    assert cls.from_c(c) == default


def test_a_struct_it_was_never_told_about():
    # the mechanism knows no struct by name: any C configuration struct gets its class
    Other = config_class("vh_camber_config_t", "Other")
    with pytest.raises(TypeError):
        Other()  # no defaults function: every field is required
    cfg = Other(window=10, min_samples=5, mag_tol_g=0.125, std_max_g=0.25)  # exact in float
    c = cfg.to_c()
    assert (c.window, c.min_samples) == (10, 5) and Other.from_c(c) == cfg


def test_what_c_cannot_hold_is_a_config_error():
    cfg = DkfConfig.default()
    for bad, match in [(dict(q=(1.0, 2.0)), "q: expected 4 values, got 2"),
                       (dict(meas="torque-only"), "measurement set 'torque-only'"),
                       (dict(disc="rk4"), "discretisation 'rk4'"),
                       (dict(jo="heavy"), "jo: 'heavy' does not fit the C field")]:
        with pytest.raises(ConfigError, match=match):
            dataclasses.replace(cfg, **bad).to_c()
    with pytest.raises(ConfigError, match="window: 70000 does not fit"):
        MeasureConfig(window=70000).to_c()  # uint16_t
    assert DkfConfig.default("speeds").meas == "speeds" and DkfConfig().meas == "speeds+torque"
