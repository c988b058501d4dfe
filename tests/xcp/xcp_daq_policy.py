"""The pyxcp DAQ policy the XCP tests collect samples with: every sample as (DAQ list number, the
slave's timestamp, the values); ``want`` samples set ``done``."""
from __future__ import annotations

import logging
import threading

from pyxcp.daq_stim import DaqOnlinePolicy


class Collect(DaqOnlinePolicy):
    def __init__(self, lists, want: int | None = None):
        super().__init__(lists, logger=logging.getLogger("xcp-test"))
        self.pid_off = False
        self.samples: list = []
        self.done = threading.Event()
        self.want = want

    def initialize(self):
        pass

    def finalize(self):
        pass

    def on_daq_list(self, daq_list, ts0, ts1, payload):
        self.samples.append((daq_list, ts1, list(payload)))
        if self.want is not None and len(self.samples) >= self.want:
            self.done.set()
