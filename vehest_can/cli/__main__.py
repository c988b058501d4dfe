"""``python -m vehest_can.cli``: the console script (tests and the demo spawn the daemon this way)."""
import sys

from . import main

sys.exit(main())
