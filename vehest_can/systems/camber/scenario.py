"""Camber inspection scenarios: TOML files of ``kind = "camber"``: a powertrain drive
(:mod:`vehest_can.sim.powertrain`) with the four wheel-mounted inspection devices of seed 002 clamped on
(``[camber]``: true camber, device misalignment, chip rotation, resolution, noise, fixture pose); the
schema is in ``docs/scenarios.md``. Shipped ones live in ``firmware_sim/scenarios/camber/``."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...paths import ShippedSet
from ...schema import Num
from ...sim.powertrain import PowertrainScenario, checked, read_powertrain
from ...sim.scenario import load_shipped

KINDS = ("camber",)

SCENARIOS = ShippedSet("scenarios/camber", "firmware_sim/scenarios/camber")
camber_scenario_dir, list_camber_scenarios, camber_scenario_path = SCENARIOS.dir, SCENARIOS.names, SCENARIOS.path

# [camber]: the four wheel-mounted inspection devices of seed 002 (FL, FR, RL, RR)
_CAMBER_POSES = {"wheel": 0, "x_down": 1, "z_down": 2}
_CAMBER = {
    "theta_deg": Num(-15.0, 15.0),    # true camber per wheel
    "psi_deg": Num(-45.0, 45.0),      # device misalignment yaw per wheel
    "chip_deg": Num(-10.0, 10.0),     # chip rotation in the device about x, y, z, per wheel
    "lsb_mg": Num(0.1, 100.0, lo_open=False),
    "noise_mg": Num(0.0, 100.0),
}


@dataclass(frozen=True)
class Camber:
    theta_deg: tuple[float, float, float, float]
    psi_deg: tuple[float, float, float, float]
    chip_deg: tuple[tuple[float, float, float], ...]
    lsb_mg: float = 4.0
    noise_mg: float = 4.0
    pose: str = "wheel"


@dataclass(frozen=True)
class CamberScenario(PowertrainScenario):
    """A powertrain scenario with the inspection devices clamped on."""

    camber: Camber | None = None  # always set by the loader (a default only because the fields before have one)

    def inspection_devices(self, ffi, lib):
        """(``vh_cambernode_config_t[4]``, pose) of the four devices."""
        cam = self.camber
        if cam is None:
            return None
        cfgs = ffi.new("vh_cambernode_config_t[4]")
        for i in range(4):
            lib.vh_cambernode_config_default(ffi.addressof(cfgs[i]))
            cfgs[i].theta_rad = np.radians(cam.theta_deg[i])
            cfgs[i].psi_rad = np.radians(cam.psi_deg[i])
            cfgs[i].chip_rad = [float(np.radians(a)) for a in cam.chip_deg[i]]
            cfgs[i].lsb_g = [cam.lsb_mg * 1e-3] * 3
            cfgs[i].noise_std_g = cam.noise_mg * 1e-3
            cfgs[i].seed = (self.node_seed + 7919 * (i + 1)) % 2**64 or 1
        return cfgs, _CAMBER_POSES[cam.pose]


def camber_scenario_from_dict(doc: dict, path: str | Path = "<scenario>") -> CamberScenario:
    """Validate an already parsed TOML document (``path`` only names it in errors)."""
    c, fields = read_powertrain(doc, path, KINDS[0], ("camber",))
    if "camber" not in doc:
        c.fail("camber", "missing (required table: the inspection devices)")
    return checked(c, CamberScenario(**fields, camber=_camber(c, doc["camber"])))


def load_camber_scenario(path: str | Path) -> CamberScenario:
    """Load and validate one camber inspection scenario (a path, or the name of a shipped one)."""
    return load_shipped(SCENARIOS, path, camber_scenario_from_dict)


def _camber(c, doc) -> Camber:
    t = c.table(doc, "camber", set(_CAMBER) | {"pose"})
    for key in ("theta_deg", "psi_deg"):
        if key not in t:
            c.fail(f"camber.{key}", "missing (required: four values, FL FR RL RR)")

    def four(key, spec, width=None):
        v = t[key]
        if not isinstance(v, list) or len(v) != 4:
            c.fail(f"camber.{key}", "must be a list of 4 entries (FL, FR, RL, RR)")
        if width is None:
            return tuple(c.number(x, f"camber.{key}[{i}]", spec) for i, x in enumerate(v))
        out = []
        for i, row in enumerate(v):
            if not isinstance(row, list) or len(row) != width:
                c.fail(f"camber.{key}[{i}]", f"must be a list of {width} angles (about x, y, z)")
            out.append(tuple(c.number(x, f"camber.{key}[{i}][{j}]", spec) for j, x in enumerate(row)))
        return tuple(out)

    pose = c.string(t.get("pose", "wheel"), "camber.pose")
    if pose not in _CAMBER_POSES:
        c.fail("camber.pose", f"{pose!r}: expected one of {', '.join(_CAMBER_POSES)}")
    return Camber(
        theta_deg=four("theta_deg", _CAMBER["theta_deg"]),
        psi_deg=four("psi_deg", _CAMBER["psi_deg"]),
        chip_deg=four("chip_deg", _CAMBER["chip_deg"], 3) if "chip_deg" in t else ((0.0, 0.0, 0.0),) * 4,
        lsb_mg=c.number(t.get("lsb_mg", 4.0), "camber.lsb_mg", _CAMBER["lsb_mg"]),
        noise_mg=c.number(t.get("noise_mg", 4.0), "camber.noise_mg", _CAMBER["noise_mg"]),
        pose=pose,
    )


__all__ = ["KINDS", "Camber", "CamberScenario", "load_camber_scenario", "camber_scenario_from_dict",
           "camber_scenario_dir", "camber_scenario_path", "list_camber_scenarios"]
