"""The car contract: what the simulator asks of a simulated car, whatever its plant.

A car is a C plant with the sensor nodes (and actuators) that talk for it on the bus, behind the C
car interface (``firmware_sim/include/vh_car.h``): ``tick`` returns the frames of one tick, ``rx``
takes a frame the ECU sent (a car whose actuators listen closes the loop), ``truth`` is the plant's
state after the tick. A subclass builds its C car, fills ``self.c`` (``vh_car_t``) in ``reset`` and
names the nodes that can secure their frames; the simulator needs nothing else, in process (one C
loop, :func:`vehest_can.sim.session.run_inprocess`) or on a bus.
"""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from ..native import ffi, lib, struct_dtype
from . import PLANTS  # noqa: F401 - re-exported beside on_plants


def played_by(car, plant: str):
    """The car `plant` plays when given `car`: its data sheet with the tyre the plant runs, the car file an
    ECU on that plant is calibrated for. Our plant ("veh14") runs the car's tyre (the 1987 set or the
    PAC2002 set) without a lateral compliance; CommonRoad's multi-body plant runs a PAC2002 set only: the
    car's own with its compliance, else that of the CommonRoad vehicle whose hidden physics it keeps
    (:func:`~vehest_can.sim.mbplant.base_vehicle`). The car itself when nothing changes."""
    if plant == "commonroad_mb" and car.pac2002_coefficients is None:
        from ..carfile import load_car
        from .mbplant import base_vehicle

        base = load_car(f"commonroad_vehicle{base_vehicle(car)}")  # its tyre as CommonRoad's car file has it
        return dataclasses.replace(car, name=f"{car.name}@{plant}", path=None, lateral_coefficients=None,
                                   longitudinal_coefficients=None, pac2002_coefficients=base.pac2002_coefficients,
                                   lateral_compliance_m_per_n=base.lateral_compliance_m_per_n)
    if plant == "veh14" and car.lateral_compliance_m_per_n != 0.0:
        return dataclasses.replace(car, name=f"{car.name}@{plant}", path=None, lateral_compliance_m_per_n=0.0)
    return car


def on_plants(sc: Any, plants: tuple[str, ...]) -> list:
    """A scenario on each of `plants` (a scenario with a choice of plant whose file names none), or
    as it is (one that names its plant, or another car's)."""
    if not hasattr(sc, "with_plant") or sc.plant_fixed:
        return [sc]
    return [sc if p == sc.plant else sc.with_plant(p) for p in plants]


class Car:
    """One simulated car. ``name``, ``n`` (ticks of its drive), ``truth_dtype`` (one record per tick),
    ``closed`` (it takes the ECU's frames), ``reset``, ``tick``, ``rx``, ``truth``, ``truths``,
    ``enable_secoc`` and ``secoc_hooks``."""

    #: the DBC nodes of this car that secure their frames when SecOC is on (enable_secoc)
    SECOC_NODES: tuple[str, ...] = ()

    def __init__(self, name: str, n: int, truth_ctype: str):
        self.name, self.n = name, n
        self.c_truth_dtype = struct_dtype(truth_ctype)  # the C car's truth record
        self.truth_dtype = self.c_truth_dtype           # the car's (truths() turns one into the other)
        self.c = ffi.new("vh_car_t *")
        self.secoc: dict[str, Any] = {}  # node -> its vehest_can.bus.secoc.BusSecoc, once enable_secoc
        self._out = ffi.new("vh_frame_t[]", lib.VH_CAR_MAX_TX)
        self._rxf = ffi.new("vh_frame_t *")

    # ---- what a car supplies ----

    def _start(self) -> None:
        """The C car at the start of its drive, ``self.c`` bound to it."""
        raise NotImplementedError

    def _attach_secoc(self) -> None:
        """Hand ``self.secoc``'s C hooks to the car's nodes."""
        raise NotImplementedError

    def truths(self, raw: np.ndarray) -> np.ndarray:
        """The car's truth records from the C car's (the same unless a car says otherwise)."""
        return raw.copy()

    # ---- the contract ----

    @property
    def closed(self) -> bool:
        """The car takes the ECU's frames (its actuators): the loop closes over the bus."""
        return self.c.rx != ffi.NULL

    def reset(self) -> None:
        """The car at the start of its drive: a new session, so SecOC restarts too (as the ECU's does)."""
        self._start()
        for s in self.secoc.values():
            s.restart()

    def enable_secoc(self, keys: dict, store=None) -> Car:
        """SecOC on for the car's nodes (SECOC_NODES), one vehest_can.bus.secoc.BusSecoc each.
        Without a store (a FreshnessStore) FVs start from 1 in each session: in-process and bus runs
        stay bit-identical; with one, each session resumes where the last left off."""
        from ..bus.secoc import BusSecoc

        self.secoc = {node: BusSecoc(node, keys, store=store) for node in self.SECOC_NODES}
        self._attach_secoc()
        return self

    def secoc_hooks(self) -> list:
        return list(self.secoc.values())

    def maintain(self) -> None:
        """Once a second of a run: each node's FV reservation kept ahead, its receivers' state stored."""
        for s in self.secoc.values():
            s.maintain()

    def tick(self, k: int) -> list:
        """Tick k: the frames the car sends (``vh_frame_t`` cdata, valid until the next tick)."""
        n = lib.vh_car_tick(self.c, k, self._out, self.c.max_tx)
        if k and k % lib.VH_SECOC_SYNC_PERIOD_TICKS == 0:
            self.maintain()
        return [self._out[i] for i in range(n)]

    def rx(self, frame) -> None:
        """One ECU frame (``can.Message`` or ``vh_frame_t`` cdata); a car that listens to none ignores it."""
        if hasattr(frame, "arbitration_id"):
            if frame.is_error_frame or frame.is_remote_frame:
                return
            from ..bus.frames import to_frame

            frame = to_frame(frame, self._rxf)
        lib.vh_car_rx(self.c, frame)

    def truth(self) -> np.void:
        """The truth after the last tick."""
        raw = np.frombuffer(ffi.buffer(lib.vh_car_truth(self.c), self.c.truth_size), dtype=self.c_truth_dtype)
        return self.truths(raw)[0]


__all__ = ["Car", "PLANTS", "on_plants"]
