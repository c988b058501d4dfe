"""One exception root, a subclass per phase (python-can style)."""


class VehestError(Exception):
    """Root of every error vehest-can raises on purpose."""


class ConfigError(VehestError, ValueError):
    """A configuration value (CLI, config file, filter tuning) is unusable."""


class ScenarioError(ConfigError):
    """A scenario file is unusable; the message names the file, the key and the problem."""


class NativeError(VehestError):
    """The C core refused a call (a VH_E* status code)."""


class BusError(VehestError):
    """A CAN bus could not be opened or used."""
