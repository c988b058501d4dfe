"""The terminal (#13 point 5) and hostile command lines (#15): progress bars and plain lines,
tables within 100 columns, notes on stderr, a closed pipe, one bitrate parser, --log always an
output, and a clear `error: ...` with a non-zero exit (no traceback) for every bad argument."""
import io
import subprocess
import sys
from pathlib import Path

import pytest

from vehest_can.cli import build_parser, main
from vehest_can.progress import Progress

ROOT = Path(__file__).parents[2]
DBCS = [str(ROOT / "dbc" / "vehest_pt.dbc"), str(ROOT / "dbc" / "vehest_ch.dbc")]


def cli(argv, capsys):
    rc = main(argv)
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return rc, out, err


# ---- progress ---------------------------------------------------------------------------------

class Tty(io.StringIO):
    def isatty(self):
        return True


def test_progress_is_a_bar_with_rate_on_a_terminal_and_plain_lines_otherwise():
    plain = io.StringIO()
    p = Progress("run", stream=plain)
    for k in range(0, 1001, 50):
        p(k, 1000)
    p.done("done")
    lines = plain.getvalue().splitlines()
    assert lines[0].startswith("run: 0%") and "run: 50%" in plain.getvalue() and lines[-1] == "run: done"
    assert "\r" not in plain.getvalue() and len(lines) <= 13
    tty = Tty()
    p = Progress("run", stream=tty)
    for k in range(0, 1001, 50):
        p(k, 1000)
    p.done("3x real time")
    text = tty.getvalue()
    assert "\r" in text and "tick/s" in text and "1.00k/1.00k" in text and "3x real time" in text


# ---- tables, notes, pipes ---------------------------------------------------------------------

def test_busload_notes_go_to_stderr_and_bitrates_take_500k(capsys):
    rc, out, err = cli(["busload", *DBCS], capsys)  # the DBCs' bit rates: noted, on stderr
    assert "note: vehest_pt: bit rate from the DBC" in err and "note:" not in out
    rc, out, err = cli(["busload", *DBCS, "-b", "500k", "--data-bitrate", "2M"], capsys)
    assert "vehest_pt  500k/2M" in out


def test_a_closed_pipe_ends_quietly():
    """`vehest-can busload ... | head`: the reader is gone before anything is written."""
    p = subprocess.Popen([sys.executable, "-m", "vehest_can.cli", "busload", *DBCS, "--frames"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()
    err = p.stderr.read().decode()
    assert p.wait(timeout=60) == 141
    assert "Broken pipe" not in err and "Traceback" not in err and "Exception ignored" not in err


def test_one_bitrate_parser_for_every_verb():
    for verb in (["sim", "launch_2nd"], ["daemon"], ["faults"], ["demo"]):
        args = build_parser().parse_args([*verb, "-b", "500k", "--data-bitrate", "2M"])
        assert (args.bitrate, args.data_bitrate) == (500_000, 2_000_000)
    assert build_parser().parse_args(["daemon", "-b", "250000"]).bitrate == 250_000


@pytest.mark.parametrize("rate", ["fast", "0", "-500k", "nan", "1.5", "inf"])
def test_a_bad_bitrate_is_a_usage_error(rate, capsys):
    with pytest.raises(SystemExit) as e:
        main(["sim", "launch_2nd", "-b", rate])
    assert e.value.code == 2
    assert "argument -b/--bitrate" in capsys.readouterr().err


def test_the_faults_table_fits_100_columns(capsys):
    rc, out, _ = cli(["faults", "--duration", "2.6", "--fault", "drop:DLS_Sensors:p=0.5:2.0-2.5"], capsys)
    assert rc == 0
    lines = out.splitlines()
    assert max(map(len, lines)) <= 100, max(lines, key=len)
    assert any("ECU detects" in line for line in lines)


# ---- --log is an output; inputs are named for what they are -----------------------------------

@pytest.mark.parametrize("verb", [["sim", "launch_2nd", "--mode", "lockstep"], ["daemon", "--mode", "lockstep"]])
def test_bad_log_outputs_are_errors_before_the_run(verb, tmp_path, capsys):
    for bad, why in ((tmp_path / "x.xyz", "unknown log format"), (tmp_path, "is a folder"),
                     (tmp_path / "nope" / "x.log", "does not exist")):
        rc, _, err = cli([*verb, "--log", str(bad)], capsys)
        assert rc == 1 and err.startswith("error:") and why in err


def test_camber_measure_reads_from_log_and_the_old_flag_warns(tmp_path, capsys):
    empty = tmp_path / "empty.log"
    empty.write_text("")
    rc, _, err = cli(["camber", "measure", "--from-log", str(empty)], capsys)
    assert rc == 1 and "no CAN data frames in this log (the file is empty)" in err
    log = tmp_path / "other.log"
    log.write_text("(0.000000) vcan0 123#00\n")  # a frame, but none of the ECU's camber frames
    rc, _, err = cli(["camber", "measure", "--from-log", str(log)], capsys)
    assert rc == 1 and "no VEHEST_Camber frame" in err and "deprecated" not in err
    rc, _, err = cli(["camber", "measure", "--log", str(log)], capsys)
    assert rc == 1 and "warning: --log is deprecated here" in err and "--from-log" in err


# ---- hostile arguments: each a clear error --------------------------------------------------

@pytest.mark.parametrize("argv", [
    ["sim", "launch_2nd", "--duration", "nan"],
    ["sim", "launch_2nd", "--duration", "inf"],
    ["sim", "launch_2nd", "--duration", "1e12"],
    ["sim", "launch_2nd", "--duration", "-1"],
    ["faults", "--duration", "nan"],
    ["faults", "--duration", "inf"],
    ["faults", "--duration", "1e12"],
    ["faults", "--bus-run", "nan"],
    ["demo", "--realtime", "-1"],
    ["demo", "--realtime", "nan"],
    ["demo", "--realtime", "inf"],
    ["replay", "x.log", "--max-gap", "nan"],
    ["camber", "bound", "--lsb-mg", "nan"],
])
def test_bad_numbers_are_errors(argv, capsys):
    rc, _, err = cli(argv, capsys)
    assert rc == 1 and err.startswith("error:")


@pytest.mark.parametrize("argv", [["monitor", "--refresh", "0"], ["monitor", "--duration", "nan"]])
def test_monitor_bounds_give_no_session_reason(argv, capsys):
    """The monitor keeps no session in memory: its bound is stated without that reason."""
    rc, _, err = cli(argv, capsys)
    assert rc == 1 and err.startswith(f"error: {argv[1]} must be a finite number of seconds > 0") and "session" not in err


def test_an_unknown_plot_format_is_an_error(tmp_path, capsys):
    rc, _, err = cli(["camber", "bound", "--plot", str(tmp_path / "x.xyz")], capsys)
    assert rc == 1 and "unknown plot format '.xyz'" in err
    rc, _, err = cli(["camber", "bound", "--plot", str(tmp_path / "no" / "x.png")], capsys)
    assert rc == 1 and "does not exist" in err


@pytest.mark.parametrize("name, content", [
    ("junk.blf", b"\x00\x01garbage" * 300),
    ("junk.db", b"not a database" * 300),
    ("junk.mf4", b"MDF     garbage" * 300),
    ("junk.asc", b"date Mon Dec  1 20:13:20 2025\nbase hex  timestamps absolute\nno internal events logged\n"
                 b"   0.000000 1  1FFFFFFFFFx     Rx   d 2 01 02\n"),  # an ID beyond 29 bits
    ("junk.log", b"(0.1) can0 123456789#00\n"),                            # likewise, candump
    ("junk.log", b"\xff\xfe\x00 not text\n"),
])
@pytest.mark.parametrize("verb", [["replay"], ["camber", "measure", "--from-log"]])
def test_unreadable_logs_are_errors(verb, name, content, tmp_path, capsys):
    if name.endswith(".mf4"):
        pytest.importorskip("asammdf")
    (tmp_path / name).write_bytes(content)
    rc, _, err = cli([*verb, str(tmp_path / name)], capsys)
    assert rc == 1 and err.startswith("error:")
    # (python-can's candump reader, behind camber, takes 123456789 for an error frame and drops it)
    assert name in err or (verb[0] == "camber" and "123456789" in content.decode("latin-1"))


def test_deeply_nested_calibration_json_is_an_error(tmp_path, capsys):
    cal = tmp_path / "deep.json"
    cal.write_text("[" * 100_000 + "]" * 100_000)
    rc, _, err = cli(["daemon", "--camber-cal", str(cal)], capsys)
    assert rc == 1 and "nested too deeply" in err


def test_the_driveline_table_fits_100_columns():
    from vehest_can.systems.driveline.report import table

    sets = [{"measurement_set": "speeds+torque", "rms_meas_minus_est_nm": 123.45, "paper_rms_meas_minus_est_nm": 6.7,
             "rms_est_minus_truth_nm": 1234.5, "sensor_noise_rms_nm": 99.9, "gain_settling_steps": 12345,
             "paper_gain_settling_steps": 100, "no_input_mean_bias_nm": -1234.5}]
    text = table([{"scenario": "tip_in_tip_out", "sets": sets}])
    assert max(map(len, text.splitlines())) <= 100 and "123.45" in text
