"""Roll system (seed 003, Zhang et al. 2017): UKF roll angle / rate estimation and sliding-mode
active roll control. ``api``: the C (in ``vehest_can._native``, float32 and double builds) over numpy
arrays; ``reference``: the independent numpy reference UKF (and EKF, filterpy wrapper); ``evaluate``:
the paper's cases against the 14-DOF plant's truth. docs/roll.md has the model, docs/results.md the figures."""
