"""Tyre force (seed 000): the SKFMEC estimator of lateral tyre forces on the 14-DOF chassis plant.

``api`` (SKFMEC double and fixed point, the plain EKF, over ``vh_skf``/``vh_skfq``), ``reference``
(numpy), ``scenario`` (the scenario kind ``tireforce``, read through :mod:`vehest_can.sim.veh14`, whose car is plant +
CHS sensor node), ``report`` (decoding, metrics, acceptance, table, plots); its scenarios are in
``firmware_sim/scenarios/tireforce/``.

Its registration (the :class:`~vehest_can.systems.System` the demo loops over) is ``system.SYSTEM``."""
