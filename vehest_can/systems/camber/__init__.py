"""Camber (seed 002): camber and misalignment of each wheel at rest from 3-axis accelerometers.

``api`` (calibration and estimator over ``vh_camber``), ``reference`` (numpy), ``inspection``
(captures, calibration from fixture logs, the ECU's results, the error bound); its scenarios are
the files in ``firmware_sim/scenarios/`` with a ``[camber]`` table.

Its registration (the :class:`~vehest_can.systems.System` the demo loops over) is ``system.SYSTEM``."""
