"""The lockstep protocol over any bus: the simulation master publishes a tick's frames and then
SIM_Sync(tick, STEP); the ECU steps once and answers with its frames and VEHEST_SyncAck(tick, n).
Both frames are in the simulator's own DBC (dbc/vehest_sim.dbc), not the car's.

The master never sends tick k+1 before the ack of tick k, so the ECU sees exactly the frames of
each tick whatever the bus's latency: runs are deterministic and equal to in-process lockstep.
"""
from __future__ import annotations

import can

from .frames import SIM, database

STEP, RESET, END = 0, 1, 2
#: RESET handshakes number their attempts from here, above every STEP tick of a session
RESET_TICK_BASE = 0x8000_0000


def _msg(name: str):
    return database(SIM).get_message_by_name(name)


SYNC = _msg("SIM_Sync")
ACK = _msg("VEHEST_SyncAck")


def sync_message(tick: int, cmd: int = STEP) -> can.Message:
    return can.Message(arbitration_id=SYNC.frame_id, is_extended_id=False,
                       data=SYNC.encode({"SyncTick": tick, "SyncCmd": cmd}))


def ack_message(tick: int, tx_count: int) -> can.Message:
    return can.Message(arbitration_id=ACK.frame_id, is_extended_id=False,
                       data=ACK.encode({"AckTick": tick, "AckTxCount": tx_count}))


def is_sync(msg: can.Message) -> bool:
    return msg.arbitration_id == SYNC.frame_id and not msg.is_extended_id and len(msg.data) == SYNC.length


def is_ack(msg: can.Message) -> bool:
    return msg.arbitration_id == ACK.frame_id and not msg.is_extended_id and len(msg.data) == ACK.length


def decode_sync(msg: can.Message) -> tuple[int, int]:
    d = SYNC.decode(msg.data, decode_choices=False)
    return int(d["SyncTick"]), int(d["SyncCmd"])


def decode_ack(msg: can.Message) -> tuple[int, int]:
    d = ACK.decode(msg.data, decode_choices=False)
    return int(d["AckTick"]), int(d["AckTxCount"])
