"""What a session gives people besides a system's own figures: its frames decoded by the DBC, a
metrics JSON, and the frames lost / deadlines missed of a real-time run."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..bus.frames import BUSES, TICK_S, database, e2e_config, message
from .session import Session


def decode(session: Session, name: str) -> dict[str, np.ndarray]:
    """Signals of every frame `name` (of either bus's DBC) in the session, by tick (NaN where a
    tick has none)."""
    msg = message(name)
    n = len(session.truth)
    out = {s.name: np.full(n, np.nan) for s in msg.signals}
    sel = session.frames["id"] == msg.frame_id
    for f, k in zip(session.frames[sel], session.frame_tick[sel]):
        if k >= n:
            continue
        values = msg.decode(bytes(f["data"][: f["len"]]), decode_choices=False)
        for key, v in values.items():
            out[key][k] = v
    return out


def write_metrics(metrics: list[dict], path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(metrics, indent=2, default=float) + "\n")


def counter_gaps(session: Session, name: str) -> tuple[int, int]:
    """(frames received, frames missing between them) of a message in a session, from its E2E
    alive counter (0..14): what was lost on the way while this side was listening."""
    msg = message(name)
    counters = [int(f["data"][1]) & 0x0F for f in session.frames[session.frames["id"] == msg.frame_id]]
    gaps = sum((b - a - 1) % 15 for a, b in zip(counters, counters[1:]))
    return len(counters), gaps


def realtime_summary(session: Session, daemon: dict) -> dict:
    """Frames lost either way, deadline misses and latency of a real-time run (car side + ECU side).

    Car -> ECU: every sensor frame sent must have arrived (the daemon counts them, and its E2E
    check counts counter skips). ECU -> car: the ECU keeps publishing before the car starts and
    after it stops listening, so losses are the gaps in the E2E alive counters of what arrived."""
    sensors_sent = int(session.stats.get("frames_sent", 0))
    got = [counter_gaps(session, m.name) for b in BUSES for m in database(b).messages
           if "VEHEST" in m.senders and e2e_config(m) is not None]
    ecu_n, ecu_gaps = sum(n for n, _ in got), sum(g for _, g in got)
    out = {
        "mode": "realtime",
        "duration_s": len(session.truth) * TICK_S,
        "sensor_frames_sent": sensors_sent,
        "sensor_frames_received_by_ecu": int(daemon.get("frames_rx", 0)),
        "ecu_counter_skips": int(daemon.get("counters", {}).get("counter_skip", 0)),
        "ecu_frames_sent": int(daemon.get("frames_tx", 0)),
        "ecu_frames_received_by_car": ecu_n,
        "ecu_frames_missing_in_counters": ecu_gaps,
        "ecu_deadline_misses": int(daemon.get("deadline_misses", 0)),
        "car_deadline_misses": int(session.stats.get("deadline_misses", 0)),
        "ecu_tick_lateness_us": daemon.get("lateness_us", {}),
        "frame_to_estimate_latency_us": daemon.get("latency_us", {}),
    }
    lost_in = max(0, sensors_sent - out["sensor_frames_received_by_ecu"]) + out["ecu_counter_skips"]
    lost_out = out["ecu_frames_missing_in_counters"]
    out["frames_lost"] = lost_in + lost_out
    lat = out["frame_to_estimate_latency_us"]
    late = out["ecu_tick_lateness_us"]
    out["line"] = (f"{out['duration_s']:.0f} s: {sensors_sent} sensor frames -> {lost_in} lost; "
                   f"{out['ecu_frames_received_by_car']} ECU frames received -> {lost_out} missing in their "
                   f"E2E counters; deadline misses ECU {out['ecu_deadline_misses']} car {out['car_deadline_misses']}; "
                   f"ECU tick lateness p50 {late.get('p50', float('nan')):.0f} µs p99 {late.get('p99', float('nan')):.0f} µs; "
                   f"frame-to-estimate latency p50 {lat.get('p50', float('nan')):.0f} µs "
                   f"p99 {lat.get('p99', float('nan')):.0f} µs")
    return out


# ---- acceptance: words people gate on, and a JUnit XML report for CI systems -------------------

PASS, FAIL = "PASS", "FAIL"
LEGEND = "PASS: the line's target is met; FAIL: it is not (the figures that decide it follow the line)"


def verdict_word(verdict) -> str:
    """A system's verdict ('pass', 'SHORT', True ...) as PASS or FAIL."""
    return PASS if verdict is True or str(verdict).strip().lower() in ("pass", "passed", "ok", "true") else FAIL


def checks_of(metrics: dict, suite: str) -> list[dict]:
    """The acceptance lines of one session's metrics (a system's ``acceptance`` list, and the
    bus-equals-in-process check of the demo) as {suite, name, passed, detail}."""
    out = []
    if "bus_equals_inprocess" in metrics:
        out.append({"suite": suite, "name": "bus lockstep == in-process lockstep",
                    "passed": bool(metrics["bus_equals_inprocess"]), "detail": ""})
    for a in metrics.get("acceptance", []):
        out.append({"suite": suite, "name": str(a.get("line", "")), "passed": verdict_word(a.get("verdict")) == PASS,
                    "detail": str(a.get("detail", ""))})
    return out


def checks_text(checks: list[dict]) -> str:
    lines = [f"  {PASS if c['passed'] else FAIL}  {c['suite']}: {c['name']}" + (f" ({c['detail']})" if c["detail"] else "")
             for c in checks]
    failed = sum(not c["passed"] for c in checks)
    lines.append(f"{len(checks) - failed} {PASS}, {failed} {FAIL}. {LEGEND}")
    return "\n".join(lines)


def write_junit(checks: list[dict], path: Path, name: str = "vehest-can demo") -> None:
    """One testsuite per scenario, one testcase per acceptance line, a <failure> where it fails."""
    import xml.etree.ElementTree as ET

    root = ET.Element("testsuites", name=name, tests=str(len(checks)),
                      failures=str(sum(not c["passed"] for c in checks)))
    for suite in dict.fromkeys(c["suite"] for c in checks):
        cs = [c for c in checks if c["suite"] == suite]
        el = ET.SubElement(root, "testsuite", name=suite, tests=str(len(cs)), failures=str(sum(not c["passed"] for c in cs)),
                           errors="0", skipped="0")
        for c in cs:
            case = ET.SubElement(el, "testcase", classname=suite, name=c["name"])
            if not c["passed"]:
                ET.SubElement(case, "failure", message=c["detail"] or FAIL).text = c["detail"]
            elif c["detail"]:
                ET.SubElement(case, "system-out").text = c["detail"]
    path.parent.mkdir(parents=True, exist_ok=True)
    ET.ElementTree(root).write(path, encoding="utf-8", xml_declaration=True)
