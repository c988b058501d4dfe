"""The driveline's fault study: both filters' health, validity and shaft torque from the raw
``VEHEST_DrivelineEst`` payload, and the fault table of ``vehest-can faults`` on the DLS sensor node."""
from __future__ import annotations

import numpy as np

from .. import FaultCase


class DrivelineFaults:
    sensor_node = "DLS"
    sensor_message = "DLS_Sensors"
    estimate_message = "VEHEST_DrivelineEst"
    filters = ("T", "S")   # DkfT (speeds + turbine torque) and DkfS (speeds only)
    error_label = "DkfT error while valid"
    error_unit = "Nm"

    #: Windows are 2.0-2.5 s of the launch scenario: both filters are OK well before.
    catalogue: tuple[FaultCase, ...] = (
        FaultCase("none (reference)", ""),
        FaultCase("random frame loss", "drop:DLS_Sensors:p=0.2:2-2.5", ("counter_skip",)),
        FaultCase("bit errors, some frames", "corrupt_crc:DLS_Sensors:p=0.2:2-2.5", ("crc_error",)),
        FaultCase("bit errors, every frame", "corrupt_crc:DLS_Sensors:2-2.5", ("crc_error", "timeout")),
        FaultCase("frozen sender (repeats its frame)", "freeze_counter:DLS_Sensors:2-2.5", ("counter_repeat", "timeout")),
        FaultCase("counter jumps", "skip_counter:DLS_Sensors:p=0.1:2-2.5", ("counter_skip",)),
        FaultCase("wrong length", "wrong_dlc:DLS_Sensors:p=0.2:2-2.5", ("dlc_error",)),
        FaultCase("sensor node silent", "silence:DLS:2-2.5", ("timeout",)),
        FaultCase("flood at ID 0x001, whole bus", "flood:2-2.5", ("unknown_id", "timeout")),
        FaultCase("same, sender keeps only its newest frame", "flood:2-2.5", ("unknown_id", "timeout"),
                  {"tx_policy": "latest"}),
        FaultCase("flood at ID 0x001, half the bus", "flood:load=0.5:2-2.5", ("unknown_id",)),
        FaultCase("constant latency 1.5 ms", "latency:DLS_Sensors:us=1500:2-2.5"),
        FaultCase("jitter 0..1 ms", "jitter:DLS_Sensors:max_us=1000:2-2.5"),
        FaultCase("jitter 0..2.5 ms", "jitter:DLS_Sensors:max_us=2500:2-2.5", ("timeout",)),
    )

    def health(self, est: np.ndarray, which: str) -> np.ndarray:
        return (est[:, 1] >> (4 if which == "T" else 6)) & 3

    def valid(self, est: np.ndarray, which: str) -> np.ndarray:
        return ((est[:, 14] >> (0 if which == "T" else 1)) & 1).astype(bool)

    def estimate(self, est: np.ndarray, which: str) -> np.ndarray:
        """The shaft torque [Nm]."""
        col = 2 if which == "T" else 6
        return est[:, col:col + 2].copy().view("<i2")[:, 0] * 0.25

    def truth(self, car) -> float:
        return car.sim.plant.truth.to


FAULTS = DrivelineFaults()
