"""The roll system's fault study (``vehest-can faults --scenario roll_paper_72kph_active``): the UKF's
and the controller's health from the raw ``VEHEST_RollEst`` payload, the roll angle estimate, and the
fault table on the roll node and the command path. Windows are 2.0-2.5 s of the active 72 km/h case:
the steer ramp is at 3.75 deg, the controller fully in (it ramps in from 0.5 s)."""
from __future__ import annotations

import numpy as np

from ...bus.frames import message
from .. import FaultCase

_SMC_PASSIVE, _SMC_FADING, _SMC_TRIPPED = 1, 4, 64   # vh_roll.h VH_ROLL_S_*


class RollFaults:
    sensor_node = "ROLL"
    sensor_message = "ROLL_Sensors"
    estimate_message = "VEHEST_RollEst"
    filters = ("UKF", "SMC")   # the estimator and the controller acting on it
    error_label = "UKF roll error while valid"
    error_unit = "deg"

    catalogue: tuple[FaultCase, ...] = (
        FaultCase("none (reference)", ""),
        FaultCase("dead suspension-deflection sensor (FL)", "sna:ROLL_Sensors:signal=SuspDeflFL:2-2.5",
                  ("signal_invalid",)),
        FaultCase("stuck vertical accelerometer (FL wheel)", "stuck:ROLL_Sensors:signal=WheelVertAccelFL:2-2.5",
                  ("signal_invalid",)),
        FaultCase("missing yaw-rate frame", "silence:ROLL_YawRate:2-2.5", ("timeout",)),
        FaultCase("lost actuator command frames", "drop:VEHEST_RollCmd:2-2.5", ("input_invalid",)),
        FaultCase("roll sensor node silent", "silence:ROLL:2-2.5", ("timeout",)),
        FaultCase("bit errors on ROLL_Sensors", "corrupt_crc:ROLL_Sensors:p=0.2:2-2.5", ("crc_error",)),
    )

    def counters_of(self, ecu):
        """The roll application's own counters (the ECU's roll side)."""
        return ecu.c.app.roll.cnt

    def _decoded(self, est: np.ndarray) -> dict[str, np.ndarray]:
        """VEHEST_RollEst's signals per tick (the payload held between frames; zeros before the first)."""
        msg = message(self.estimate_message)
        rows, inverse = np.unique(est, axis=0, return_inverse=True)
        values = [msg.decode(bytes(r[: msg.length]), decode_choices=False) for r in rows]
        return {s.name: np.array([float(v[s.name]) for v in values])[inverse.ravel()] for s in msg.signals}

    def health(self, est: np.ndarray, which: str) -> np.ndarray:
        d = self._decoded(est)
        if which == "UKF":
            return d["RollUkf_Health"].astype(int)
        smc = d["RollSmc_Health"].astype(int)
        return np.select([smc & _SMC_TRIPPED != 0, smc & _SMC_FADING != 0, smc & _SMC_PASSIVE != 0], [3, 2, 0], 1)

    def valid(self, est: np.ndarray, which: str) -> np.ndarray:
        d = self._decoded(est)
        if which == "UKF":
            return d["RollUkf_Valid"] == 1
        smc = d["RollSmc_Health"].astype(int)
        return (smc & (_SMC_TRIPPED | _SMC_PASSIVE)) == 0

    def estimate(self, est: np.ndarray, which: str) -> np.ndarray:
        """The UKF's roll angle [deg]."""
        return np.degrees(self._decoded(est)["RollEstAngle"])

    def truth(self, car) -> float:
        return float(np.degrees(car.truth()["phi"]))


FAULTS = RollFaults()
