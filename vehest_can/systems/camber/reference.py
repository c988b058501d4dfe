"""Independent float64 numpy reference of the camber paper (seed 002), written from the paper.

Nothing here calls the C core: the tests hold the C against these functions and against the
simulated truth. Equation numbers are the paper's. Frames: V vehicle (x fwd, y right, z down),
W = V rotated by camber theta about x, S = W rotated by misalignment yaw psi about y, A = chip.
Accelerations use the paper's sign (an axis pointing down reads +g); angles in rad.
"""
from __future__ import annotations

import numpy as np

# ---- Frames (eq. 1-3) ------------------------------------------------------------------

def rot_v_w(theta: float) -> np.ndarray:
    """eq. 1: [x y z]_V = R [x y z]_W, rotation by theta about x."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_w_s(psi: float) -> np.ndarray:
    """eq. 2: [x y z]_W = R [x y z]_S, rotation by psi about y."""
    c, s = np.cos(psi), np.sin(psi)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_v_s(theta: float, psi: float) -> np.ndarray:
    """eq. 3 as the product of eq. 1 and eq. 2."""
    return rot_v_w(theta) @ rot_w_s(psi)


def rot_v_s_printed(theta: float, psi: float) -> np.ndarray:
    """eq. 3 exactly as printed in the paper (and the digest), to check against the product."""
    ct, st, cp, sp = np.cos(theta), np.sin(theta), np.cos(psi), np.sin(psi)
    return np.array([[cp, 0.0, sp], [st * sp, ct, -st * cp], [-ct * sp, st, ct * cp]])


def gravity_s(theta, psi, g: float = 1.0) -> np.ndarray:
    """(0, 0, g)_V expressed in S: R_VS^T (0, 0, g). Vectorised over theta, psi (last axis = xyz)."""
    theta, psi = np.broadcast_arrays(np.asarray(theta, float), np.asarray(psi, float))
    return g * np.stack([-np.cos(theta) * np.sin(psi), np.sin(theta), np.cos(theta) * np.cos(psi)], axis=-1)


# ---- Angles (eq. 4-6) ------------------------------------------------------------------

def psi_eq4(a_s) -> np.ndarray:
    """eq. 4: psi = -atan(ax / az) (valid for az > 0, i.e. |psi| < 90 deg)."""
    a = np.asarray(a_s, float)
    return -np.arctan(a[..., 0] / a[..., 2])


def theta_eq5(a_s) -> np.ndarray:
    """eq. 5: theta = atan(ay / (az cos psi - ax sin psi)) with psi from eq. 4."""
    a = np.asarray(a_s, float)
    psi = psi_eq4(a)
    return np.arctan(a[..., 1] / (a[..., 2] * np.cos(psi) - a[..., 0] * np.sin(psi)))


def theta_eq6(a_s) -> np.ndarray:
    """eq. 6: theta = atan(ay / sqrt(ax^2 + az^2)), free of psi."""
    a = np.asarray(a_s, float)
    return np.arctan(a[..., 1] / np.sqrt(a[..., 0] ** 2 + a[..., 2] ** 2))


# ---- Error analysis (eq. 20-23) --------------------------------------------------------

def dtheta_eq21(theta, psi, da, g: float = 1.0):
    """eq. 20/21 as printed: (1/g)(-sin th sin psi dax + cos th day - sin th cos psi daz)."""
    da = np.asarray(da, float)
    st, ct, sp, cp = np.sin(theta), np.cos(theta), np.sin(psi), np.cos(psi)
    return (-st * sp * da[..., 0] + ct * da[..., 1] - st * cp * da[..., 2]) / g


def theta_gradient(theta, psi, g: float = 1.0) -> np.ndarray:
    """d theta / d(ax, ay, az) of eq. 6 at a = gravity_s(theta, psi, g), derived here.

    (sin th sin psi, cos th, -sin th cos psi) / g. The paper's eq. 20 prints -sin th sin psi for
    the ax term; with eq. 3-4 as printed (ax = -g cos th sin psi) the sign is +. The worst case
    (eq. 22) takes absolute values, so the bound is the same either way.
    """
    st, ct, sp, cp = np.sin(theta), np.cos(theta), np.sin(psi), np.cos(psi)
    return np.stack(np.broadcast_arrays(st * sp, ct, -st * cp), axis=-1) / g


def worst_case_error(theta, psi, da, g: float = 1.0):
    """eq. 22: |d theta| <= (1/g)(|sin th sin psi da_x| + |cos th da_y| + |sin th cos psi da_z|)."""
    da = np.asarray(da, float)
    st, ct, sp, cp = np.sin(theta), np.cos(theta), np.sin(psi), np.cos(psi)
    return (np.abs(st * sp * da[..., 0]) + np.abs(ct * da[..., 1]) + np.abs(st * cp * da[..., 2])) / g


def min_error_eq23(da_y: float, g: float = 1.0) -> float:
    """eq. 23: the minimum over theta, psi of eq. 22 (at theta = 0) is |da_y| / g."""
    return abs(da_y) / g


# ---- Calibration (eq. 7-19) ------------------------------------------------------------

def objective_eq7(mean, samples) -> float:
    """eq. 7: J = sum_i |mean - s_i|^2."""
    d = np.asarray(samples, float) - np.asarray(mean, float)
    return float(np.sum(d * d))


def constraint_eq8(mean, samples) -> float:
    """eq. 8: |mean|^2 - (sum_i |s_i| / N)^2 (zero at the optimum)."""
    s = np.asarray(samples, float)
    r = np.mean(np.linalg.norm(s, axis=1))
    return float(np.dot(mean, mean) - r * r)


def lagrange_multiplier_eq13(samples) -> float:
    """eq. 13: lambda = N (|sum_i s_i| / sum_i |s_i| - 1)."""
    s = np.asarray(samples, float)
    return len(s) * (np.linalg.norm(s.sum(axis=0)) / np.linalg.norm(s, axis=1).sum() - 1.0)


def constrained_mean_eq10_12(samples) -> np.ndarray:
    """eq. 10-12 with eq. 13: mean = sum_i s_i / (N + lambda)."""
    s = np.asarray(samples, float)
    return s.sum(axis=0) / (len(s) + lagrange_multiplier_eq13(s))


def constrained_mean(samples) -> np.ndarray:
    """eq. 14-16: mean_k = (sum s_k / N) * sum_i |s_i| / |sum_i s_i|, for an (N, 3) capture."""
    s = np.asarray(samples, float)
    total = s.sum(axis=0)
    return total / len(s) * np.linalg.norm(s, axis=1).sum() / np.linalg.norm(total)


def unit(v) -> np.ndarray:
    """eq. 17-18: the calibration mean scaled to a unit vector."""
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def calibration_matrix(x_down_samples, z_down_samples):
    """eq. 14-19 from two (N, 3) captures in g: returns (x, y, z unit axes in A, M, M^-1).

    M has the S axes (as seen in A) as columns, so a_A = M a_S and a_S = M^-1 a_A (eq. 19).
    """
    x = unit(constrained_mean(x_down_samples))
    z = unit(constrained_mean(z_down_samples))
    y = np.cross(z, x)
    m = np.column_stack([x, y, z])
    return x, y, z, m, np.linalg.inv(m)


def resolution_in_s(m_inv, lsb) -> np.ndarray:
    """Per-axis chip errors |e_A,j| <= lsb_j bound the S-axis errors by |M^-1| lsb (row sums)."""
    return np.abs(np.asarray(m_inv, float)) @ np.asarray(lsb, float)


def chip_rotation(angles) -> np.ndarray:
    """R_SA = Rz(c2) Ry(c1) Rx(c0): a chip rotated inside the device, a_S = R_SA a_A."""
    a, b, c = angles
    rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rz = np.array([[np.cos(c), -np.sin(c), 0], [np.sin(c), np.cos(c), 0], [0, 0, 1]])
    return rz @ ry @ rx
