"""c_core/common/vh_mathf.c, the float32 sin/cos/atan/atan2 of the firmware (the same bits on the ECU
and the host: tests/test_pil.py), against double libm over the ranges the float32 paths use: roll's
model calls sin/cos of steer, roll and pitch angles and sin(C atan(B tan a)) (|argument| <= 2.1,
atan of any real), camber atan2 of accelerations and sin/cos of the angles it gets. The error is in
float32 ulps of the exact value (|got - exact| / spacing(exact)); a correctly rounded function
has 0.5 at most. Run as a script, it prints the table."""
import math

import numpy as np
import pytest

from vehest_can.native import lib

#: (function, its double reference, range, max ulp allowed): the measured maximum with a margin
CASES = [
    ("vh_sinf", np.sin, (-math.pi, math.pi), 1.5),
    ("vh_sinf", np.sin, (-100.0, 100.0), 1.5),
    ("vh_sinf", np.sin, (-1e-3, 1e-3), 0.5),
    ("vh_cosf", np.cos, (-math.pi, math.pi), 1.5),
    ("vh_cosf", np.cos, (-100.0, 100.0), 1.5),
    ("vh_atanf", np.arctan, (-3.0, 3.0), 2.5),
    ("vh_atanf", np.arctan, (-100.0, 100.0), 2.5),
    ("vh_atanf", np.arctan, (-1e6, 1e6), 2.5),
    ("vh_atan2f", np.arctan2, (-20.0, 20.0), 2.5),
]


def ulp_error(got: np.ndarray, exact: np.ndarray) -> np.ndarray:
    spacing = np.spacing(np.abs(exact).astype(np.float32)).astype(np.float64)
    return np.abs(got.astype(np.float64) - exact) / spacing


def measure(name, ref, lo, hi, n=100_000, seed=1):
    f = getattr(lib, name)
    rng = np.random.default_rng(seed)
    if name == "vh_atan2f":
        x = rng.uniform(lo, hi, (n, 2)).astype(np.float32)
        got = np.array([f(float(a), float(b)) for a, b in x], np.float32)
        return ulp_error(got, ref(x[:, 0].astype(np.float64), x[:, 1].astype(np.float64)))
    x = rng.uniform(lo, hi, n).astype(np.float32)
    got = np.array([f(float(v)) for v in x], np.float32)
    return ulp_error(got, ref(x.astype(np.float64)))


@pytest.mark.parametrize("name,ref,rng,bound", CASES, ids=[f"{c[0]}{c[2]}" for c in CASES])
def test_accuracy_against_double_libm(name, ref, rng, bound):
    e = measure(name, ref, *rng)
    print(f"{name} on [{rng[0]:g}, {rng[1]:g}]: max {e.max():.2f} ulp")
    assert e.max() <= bound


def test_exact_where_exact_and_special_values():
    assert lib.vh_sinf(0.0) == 0.0 and lib.vh_cosf(0.0) == 1.0 and lib.vh_atanf(0.0) == 0.0
    assert lib.vh_sinf(-1e-20) == np.float32(-1e-20)  # sin x = x below the first term's ulp
    for v in (math.nan, math.inf, -math.inf, 2.0 ** 24):
        assert math.isnan(lib.vh_sinf(v)) and math.isnan(lib.vh_cosf(v))
    assert lib.vh_atan2f(math.inf, -math.inf) == pytest.approx(3 * math.pi / 4, rel=3e-7)
    assert lib.vh_atan2f(-math.inf, math.inf) == pytest.approx(-math.pi / 4, rel=3e-7)
    assert math.isnan(lib.vh_atanf(math.nan)) and math.isnan(lib.vh_atan2f(math.nan, 1.0))
    pio2 = float(np.float32(math.pi / 2))
    assert lib.vh_atanf(math.inf) == pio2 and lib.vh_atanf(-math.inf) == -pio2
    # the four quadrants and the axes
    pi = float(np.float32(math.pi))
    assert lib.vh_atan2f(0.0, 1.0) == 0.0 and lib.vh_atan2f(0.0, -1.0) == pi
    assert lib.vh_atan2f(1.0, 0.0) == pio2 and lib.vh_atan2f(-1.0, 0.0) == -pio2
    for y, x in ((1.0, 1.0), (1.0, -1.0), (-1.0, -1.0), (-1.0, 1.0), (1e-30, -1.0), (-1e-30, -1.0)):
        assert lib.vh_atan2f(y, x) == pytest.approx(math.atan2(y, x), rel=3e-7)


def test_odd_and_even():
    x = np.random.default_rng(2).uniform(-50.0, 50.0, 2000).astype(np.float32)
    for v in map(float, x):
        assert lib.vh_sinf(-v) == -lib.vh_sinf(v) and lib.vh_cosf(-v) == lib.vh_cosf(v)
        assert lib.vh_atanf(-v) == -lib.vh_atanf(v)


if __name__ == "__main__":
    for name, ref, (lo, hi), _bound in CASES + [("vh_sinf", np.sin, (-8192.0, 8192.0), None),
                                               ("vh_cosf", np.cos, (-8192.0, 8192.0), None)]:
        e = measure(name, ref, lo, hi)
        print(f"{name:10s} [{lo:>9g}, {hi:<9g}]  max {e.max():5.2f} ulp   rms {np.sqrt(np.mean(e ** 2)):.3f}"
              f"   > 0.5 ulp: {100 * np.mean(e > 0.5):5.2f} %")
