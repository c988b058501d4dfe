"""The XCP traffic in the bus budget: the generated XCP-bus DBC has the slave's one frame per tick
(VH_ECU_XCP_MAX_TX: a RES or a DTO) cyclic and the master's CRO as an event frame; a master in
standard mode sends a CRO only after the RES of the one before, so per tick the bus carries a CRO
and its RES or a DTO (ecu_desc.worst_case_frames). `vehest-can busload` counts the cyclic part,
and every bus, the XCP bus with its worst case, stays within 60 %."""
from __future__ import annotations

import json

import cantools
import pytest

from vehest_can.bus.busload import bus_load, frame_bits, wire_time_us
from vehest_can.cli import main
from vehest_can.native import lib
from vehest_can.paths import dbc_dir
from vehest_can.xcp import ecu as xcp_ecu
from vehest_can.xcp import ecu_desc


def _pct(desc, lengths) -> float:
    return 100 * sum(wire_time_us(frame_bits(n, fd=True, brs=True), 500000, 4000000) for n in lengths) / desc.tick_us


def test_the_xcp_bus_dbc_is_the_firmwares_worst_case():
    desc = xcp_ecu.description()
    assert lib.VH_ECU_XCP_MAX_TX == 1
    db = cantools.database.load_file(ecu_desc.SHIPPED_DBC)
    cro, dto = db.get_message_by_name("XCP_CRO"), db.get_message_by_name("XCP_DTO")
    assert (cro.frame_id, cro.length, dto.frame_id, dto.length) == (desc.cro_id, desc.max_cto, desc.dto_id,
                                                                     max(desc.max_cto, desc.max_dto))
    load = bus_load(ecu_desc.SHIPPED_DBC)
    assert abs(load.worst_pct - _pct(desc, [max(desc.max_cto, desc.max_dto)])) < 1e-9  # the slave's frame per tick
    assert ecu_desc.worst_case_frames(desc) == [(desc.max_cto, desc.max_cto), (desc.max_dto,)]


def test_the_xcp_bus_worst_case_is_within_60_percent_and_an_8_byte_value_fits_one_command():
    desc = xcp_ecu.description()
    worst = max(_pct(desc, frames) for frames in ecu_desc.worst_case_frames(desc))
    print(f"XCP bus worst case per tick: CRO + RES {_pct(desc, (desc.max_cto,) * 2):.2f} %, "
          f"DTO {_pct(desc, (desc.max_dto,)):.2f} %")
    assert 50.0 < worst <= 60.0  # 54.3 %: a CRO and its RES of 24 bytes each
    assert desc.fd and desc.max_cto - 2 >= 8  # DOWNLOAD: command, count, 8 bytes; UPLOAD's RES: PID, 8 bytes


def test_the_xcp_identifiers_are_apart_from_every_dbc_frame():
    desc = xcp_ecu.description()
    ids = {m.frame_id for p in dbc_dir().glob("vehest_*.dbc") for m in cantools.database.load_file(p).messages}
    assert desc.cro_id not in ids and desc.dto_id not in ids


def test_busload_counts_the_xcp_bus_and_every_bus_is_within_60_percent(capsys):
    paths = [str(p) for p in sorted(dbc_dir().glob("vehest_*.dbc"))] + [str(ecu_desc.SHIPPED_DBC)]
    assert main(["busload", *paths, "--json"]) == 0
    buses = {b["bus"]: b for b in json.loads(capsys.readouterr().out)["buses"]}
    assert set(buses) == {"vehest_pt", "vehest_ch", "vehest_sim", "vehest_xcp"}
    assert all(b["worst_pct"] <= 60.0 for b in buses.values()), {k: b["worst_pct"] for k, b in buses.items()}
    assert 35.0 < buses["vehest_xcp"]["worst_pct"] <= 60.0  # 39.2 %: one 48-byte frame per tick


@pytest.mark.rebuild
def test_the_ecu_tick_bench_runs_the_daq_within_its_budget():
    """`vehest-can bench`'s XCP rows: the figures are measured, not asserted; the DAQ must run."""
    import shutil

    import pytest

    from vehest_can.tools import bench

    if shutil.which("cc") is None:
        pytest.skip("no C compiler")
    rows = bench.c_loop("vh_bench_ecu_xcp.c")
    assert {"ecu_tick_no_xcp", "ecu_tick_xcp_idle", "ecu_tick_xcp_daq"} <= set(rows)
    assert rows["xcp_daq_dtos"] == (40000.0, 0.0)  # 2 DTOs per 1 ms = one per tick, none dropped
    text = bench.table({"array_api_ns": 1.0, "single_cffi_ns": 1.0, "numpy_ref_ns": 1.0, "ecu_xcp": rows})
    assert "ECU tick, XCP 18-signal DAQ at 1 ms" in text
