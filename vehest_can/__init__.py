"""vehest-can: a vehicle state estimator ECU on a CAN bus, around a fixed-step C core."""
from .errors import ConfigError, ScenarioError, VehestError

__version__ = "0.1.0"
__all__ = ["VehestError", "ConfigError", "ScenarioError", "__version__"]
