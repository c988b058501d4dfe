"""Driveline (seed 001): the Kalman filter of shaft torques from speeds (and turbine torque).

``api`` (DrivelineKF over ``vh_dkf``), ``reference`` (numpy), ``report`` (metrics, table, plots);
its scenarios are the files in ``firmware_sim/scenarios/`` without a ``[camber]`` table.

Its registration (the :class:`~vehest_can.systems.System` the demo loops over) is ``system.SYSTEM``."""
