"""`vehest-can monitor` on a terminal: its keys, pressed in a pseudo-terminal, and the screen read back
through a terminal emulator (pyte); the monitor listens on a host-only bus of the test's own, where
the test sends a driveline session's frames, a frame of an ID in no bundled DBC and one of an ID only
the user's --dbc describes."""
import curses
import fcntl
import os
import pty
import re
import struct
import subprocess
import sys
import termios
import threading
import time

import can
import pytest

from vehest_can.bus.bus import cli_args, open_bus, private_multicast
from vehest_can.bus.frames import unused_frame_id
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.sim.session import run_inprocess
from vehest_can.systems.driveline.scenario import load_driveline_scenario
from vehest_can.systems.ecu import Ecu

pyte = pytest.importorskip("pyte", reason="pyte (a test dependency) reads the screen back")
pytestmark = pytest.mark.multicast

ROWS, COLS = 16, 110  # fewer rows than lines: the screen scrolls
OWN_ID = unused_frame_id()  # decoded by the user's DBC only
STRAY_ID = 0x1ABCDEF       # an extended ID in no DBC: shown raw

DBC = f"""VERSION ""

NS_ :

BS_:

BU_: BENCH

BO_ {OWN_ID} BENCH_Probe: 8 BENCH
 SG_ ProbeTemp : 0|16@1+ (0.1,-40) [-40|6513.5] "degC" Vector__XXX
 SG_ ProbeCount : 16|8@1+ (1,0) [0|255] "" Vector__XXX
"""


class _Screen(pyte.Screen):
    """pyte's screen with ECMA-48's SU and SD (scroll the margins up or down n lines), which curses uses
    when lines move and pyte 0.8 does not know."""

    def scroll_up(self, count: int = 1, *_args, **_kw) -> None:
        top, bottom = self.margins or (0, self.lines - 1)
        self.save_cursor()
        self.cursor_position(bottom + 1, 1)
        for _ in range(max(1, count)):
            self.index()
        self.restore_cursor()

    def scroll_down(self, count: int = 1, *_args, **_kw) -> None:
        top, bottom = self.margins or (0, self.lines - 1)
        self.save_cursor()
        self.cursor_position(top + 1, 1)
        for _ in range(max(1, count)):
            self.reverse_index()
        self.restore_cursor()


class _Stream(pyte.ByteStream):
    csi = {**pyte.ByteStream.csi, "S": "scroll_up", "T": "scroll_down"}


class Term:
    """The monitor in a pseudo-terminal of ROWS x COLS, its output fed to a pyte screen."""

    def __init__(self, args: list[str]):
        self.screen = _Screen(COLS, ROWS)
        self.stream = _Stream(self.screen)
        self.lock = threading.Lock()
        master, slave = pty.openpty()
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", ROWS, COLS, 0, 0))
        env = {**os.environ, "TERM": "screen", "LINES": str(ROWS), "COLUMNS": str(COLS)}
        self.proc = subprocess.Popen([sys.executable, "-m", "vehest_can.cli", "monitor", "--refresh", "0.1", *args],
                                     stdin=slave, stdout=slave, stderr=subprocess.PIPE, env=env, start_new_session=True)
        os.close(slave)
        self.master = master
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()
        curses.setupterm("screen", sys.__stdout__.fileno() if sys.__stdout__.isatty() else os.open(os.devnull, os.O_WRONLY))

    def _read(self) -> None:
        while True:
            try:
                data = os.read(self.master, 65536)
            except OSError:
                return
            if not data:
                return
            with self.lock:
                self.stream.feed(data)

    def text(self) -> str:
        with self.lock:
            return "\n".join(self.screen.display)

    def key(self, keys: str | bytes) -> None:
        os.write(self.master, keys.encode() if isinstance(keys, str) else keys)

    def cap(self, name: str) -> bytes:
        return curses.tigetstr(name)

    def wait(self, cond, what: str, timeout: float = 30.0, keys: bytes | None = None) -> str:
        if keys is not None:
            self.key(keys)
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            text = self.text()
            if cond(text):
                return text
            if self.proc.poll() is not None:
                break
            time.sleep(0.1)
        raise AssertionError(f"{what}: not on the screen within {timeout} s; the screen:\n{self.text()}")

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        os.close(self.master)


def lines(text: str) -> tuple[int, int, int]:
    """The bottom line's "lines A-B of N"."""
    a, b, n = re.search(r"lines (\d+)-(\d+) of (\d+)", text).groups()
    return int(a), int(b), int(n)


def frames_of(text: str) -> int:
    return int(re.search(r"vehest-can monitor: (\d+) frames", text).group(1))


@pytest.fixture(scope="module")
def session_frames():
    s = run_inprocess(powertrain_car(load_driveline_scenario("launch_2nd"), duration_s=0.5), Ecu())
    return list(s.messages())


def test_monitor_keys_in_a_terminal(tmp_path, session_frames):
    config = private_multicast()
    (tmp_path / "bench.dbc").write_text(DBC)
    term = Term(["--dbc", str(tmp_path / "bench.dbc"), *cli_args(config)])
    bus = open_bus(config)
    stop = threading.Event()

    def feed() -> None:  # ~1,000 frames/s, round and round the session, with the two extra IDs
        i = 0
        while not stop.is_set():
            for m in session_frames[i % len(session_frames):][:20]:
                bus.send(m)
            i += 20
            bus.send(can.Message(arbitration_id=OWN_ID, is_extended_id=False, data=bytes([0xA0, 0x01, 7, 0, 0, 0, 0, 0])))
            bus.send(can.Message(arbitration_id=STRAY_ID, is_extended_id=True, data=b"\xde\xad\xbe\xef"))
            stop.wait(0.02)

    feeder = threading.Thread(target=feed, daemon=True)
    try:
        feeder.start()
        # every frame decoded: the sensor node's too, and the user's DBC's
        text = term.wait(lambda t: "DLS_Sensors:" in t and "EngineSpeed=" in t and "BENCH_Probe:" in t,
                         "the decoded view")
        assert text.startswith("vehest-can monitor:")
        assert "ProbeTemp=1.6 degC" in text and "ProbeCount=7" in text, text  # 0x01A0 * 0.1 - 40
        assert "q quit" in text.splitlines()[-1]  # the keys, on the bottom line

        # the screen scrolls: a line, a page, a line back, the end, home
        assert "lines 1-" in text
        term.key("j")
        term.wait(lambda t: "lines 2-" in t, "one line down")
        text = term.wait(lambda t: lines(t)[0] > 2, "a page down", keys=term.cap("knp"))
        first = lines(text)[0]
        term.key(term.cap("kcuu1"))
        term.wait(lambda t: lines(t)[0] == first - 1, "one line up (arrow)")
        term.key(term.cap("kend"))
        term.wait(lambda t: lines(t)[1] == lines(t)[2], "End")
        term.key(term.cap("khome"))
        term.wait(lambda t: lines(t)[0] == 1, "Home")

        # filter by signal: only the signals that match, in the messages that have them
        term.key("f")
        term.wait(lambda t: "Filter (regex" in t, "the filter prompt")
        term.key("cnttimeout|engine\r")
        text = term.wait(lambda t: "filter /cnttimeout|engine/" in t and "DLS_Sensors:" in t, "the signal filter")
        assert "CntTimeout=" in text and "EngineSpeed=" in text
        assert "CntCrcError" not in text and "ShaftTorque" not in text and "BENCH_Probe" not in text
        # by message name; Esc leaves the filter as it was
        term.key("/\x15bench\r")  # Ctrl-U: a new filter, not the old one extended
        text = term.wait(lambda t: "filter /bench/" in t, "the message filter")
        assert "BENCH_Probe:" in text and "DLS_Sensors" not in text and "VEHEST_Status" not in text
        term.key("/xyz\x1b")
        text = term.wait(lambda t: "filter /bench/" in t and "Filter (regex" not in t, "Esc")
        assert "BENCH_Probe:" in text
        term.key("f\x15\r")  # Ctrl-U empties it: no filter
        term.wait(lambda t: "filter /" not in t and "DLS_Sensors:" in t, "no filter")

        # the raw view: payloads in hex, the ID in no DBC among them
        term.key("x")
        text = term.wait(lambda t: "01ABCDEF" in t and "DE AD BE EF" in t, "the raw view")
        assert re.search(r"pt\s+100\s+DLS_Sensors\s+\d+\s+\d+/s .* FD BRS \[20\]", text), text
        assert "raw" in text.splitlines()[-1]
        term.key("x")
        term.wait(lambda t: "EngineSpeed=" in t, "back to the decoded view")

        # pause: the screen stands still while frames go on arriving; play again
        term.key("p")
        text = term.wait(lambda t: "PAUSED" in t, "paused")
        n = frames_of(text)
        time.sleep(1.0)
        assert frames_of(term.text()) == n
        term.key("p")
        term.wait(lambda t: "PAUSED" not in t and frames_of(t) > n + 200, "playing again")

        # reset: the counts start again
        before = frames_of(term.text())
        term.key("r")
        term.wait(lambda t: frames_of(t) < before, "reset")

        term.key("q")
        assert term.proc.wait(timeout=10) == 0, term.proc.stderr.read().decode()
    finally:
        stop.set()
        feeder.join(timeout=5)
        bus.shutdown()
        term.close()


@pytest.mark.parametrize("content, message", [
    (None, "no such file"),
    ("BO_ not a dbc at all {", "not a database cantools reads"),
])
def test_a_bad_dbc_is_a_clear_error(tmp_path, content, message):
    path = tmp_path / "x.dbc"
    if content is not None:
        path.write_text(content)
    out = subprocess.run([sys.executable, "-m", "vehest_can.cli", "monitor", "--once", "--duration", "0.1",
                          "--dbc", str(path)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 1 and message in out.stderr and "Traceback" not in out.stderr, out.stderr
