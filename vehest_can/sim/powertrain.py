"""The powertrain car: the plant of seed 001 (engine, converter, gearbox, shafts, wheels) and its sensor
node DLS (``vh_dlsim_t``), with the four inspection accelerometers CIS of seed 002 clamped on when a
scenario carries them, driven by one throttle and gear per tick."""
from __future__ import annotations

import numpy as np

from ..bus.frames import TICK_S
from ..native import check, ffi, lib
from .car import Car


class PowertrainCar(Car):
    """``vh_dlsim_t`` behind the car contract. ``throttle`` (in [0, 1]) and ``gear`` per tick may be
    changed between runs; each ``reset`` binds the car to them."""

    SECOC_NODES = ("DLS", "CIS")

    def __init__(self, name: str, throttle, gear, plant_params, plant_seed: int, node_config, *,
                 initial_speed: float = 0.0, camber: tuple | None = None):
        """`plant_params`: ``vh_dlp_params_t *``; `node_config`: ``vh_dls_config_t *``; `initial_speed`
        [m/s] > 0 starts rolling in gear[0]; `camber`: (``vh_cambernode_config_t[4]``, pose) of the
        inspection devices, or None."""
        super().__init__(name, len(throttle), "vh_dlp_truth_t")
        self.throttle = np.ascontiguousarray(throttle, dtype=np.float64)
        self.gear = np.ascontiguousarray(gear, dtype=np.uint8)
        self.initial_speed = initial_speed
        self.sim = ffi.new("vh_dlsim_t *")
        check(lib.vh_dlsim_init(self.sim, plant_params, plant_seed, node_config), "car set-up")
        if camber is not None:
            check(lib.vh_dlsim_set_camber(self.sim, *camber), "camber inspection devices")
        self.reset()

    def _start(self) -> None:
        self.throttle = np.ascontiguousarray(self.throttle, dtype=np.float64)
        self.gear = np.ascontiguousarray(self.gear, dtype=np.uint8)
        if len(self.gear) != len(self.throttle) or not len(self.throttle):
            raise ValueError(f"car {self.name}: throttle and gear need one value per tick, alike in number")
        self.n = len(self.throttle)
        lib.vh_dlsim_reset(self.sim)
        if self.initial_speed > 0:
            check(lib.vh_dlp_set_rolling(ffi.addressof(self.sim.plant), self.initial_speed, int(self.gear[0])),
                  "initial speed")
        lib.vh_dlsim_car(self.sim, ffi.from_buffer("double[]", self.throttle),
                         ffi.from_buffer("uint8_t[]", self.gear), len(self.throttle), self.c)

    def _attach_secoc(self) -> None:
        lib.vh_dlsim_set_secoc(self.sim, self.secoc["DLS"].c, self.secoc["CIS"].c)


def powertrain_car(scenario, duration_s: float | None = None) -> PowertrainCar:
    """A powertrain scenario's car (:class:`vehest_can.sim.scenario.Scenario`). A longer duration repeats
    the scenario's driver profile."""
    duration = scenario.duration_s if duration_s is None else duration_s
    n = int(round(duration / TICK_S))
    t = ((np.arange(n) + 1) * TICK_S) % scenario.duration_s  # the scenario's times(), repeated
    return PowertrainCar(scenario.name, scenario.throttle_at(t), np.full(n, scenario.gear, dtype=np.uint8),
                        scenario.plant_params(ffi, lib), scenario.seed, scenario.node_config(ffi, lib),
                        initial_speed=scenario.initial_speed_kmh / 3.6, camber=scenario.camber_configs(ffi, lib))


__all__ = ["PowertrainCar", "powertrain_car"]
