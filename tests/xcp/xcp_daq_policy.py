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


def one_offset(daq: list[dict], frames: dict, offsets, same) -> tuple[int, int]:
    """The one tick offset under which every DAQ sample equals its frame (``frames[tick - offset]``,
    ``same(sample, frame)``), and how many samples had a frame; asserts that exactly one fits."""
    results = {}
    for off in offsets:
        n, bad = 0, 0
        for s in daq:
            f = frames.get(s["tick"] - off)
            if f is None:
                continue
            n += 1
            if not same(s, f):
                bad = 1
                break
        results[off] = (n, bad)
    good = [off for off, (_, bad) in results.items() if bad == 0]
    assert len(good) == 1, results
    return good[0], results[good[0]][0]
