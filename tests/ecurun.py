"""Driving an in-process ECU (vehest_can.systems.ecu.Ecu) tick by tick in a test."""
from vehest_can.bus.frames import message


def run_ecu(ecu, frames_per_tick, names):
    """Each tick's frames into ``ecu.rx``, then one ``ecu.step()``; returns one list per message name
    of ``names``: the decoded frames the ECU sent (physical values, no choices), in order."""
    msgs = {message(n).frame_id: (i, message(n)) for i, n in enumerate(names)}
    out = tuple([] for _ in names)
    for frames in frames_per_tick:
        for f in frames:
            ecu.rx(f)
        for m in ecu.step():
            if m.arbitration_id in msgs:
                i, msg = msgs[m.arbitration_id]
                out[i].append(msg.decode(m.data, decode_choices=False))
    return out
