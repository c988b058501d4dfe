"""The XCP traffic in the bus budget: the generated XCP-bus DBC says the firmware's worst case
(one RES/DTO of MAX_DTO bytes per tick, VH_ECU_XCP_MAX_TX; one CRO per answer), `vehest-can
busload` counts it, and every bus stays within 60 %."""
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


def test_the_xcp_bus_dbc_is_the_firmwares_worst_case():
    desc = xcp_ecu.description()
    assert lib.VH_ECU_XCP_MAX_TX == 1
    db = cantools.database.load_file(ecu_desc.SHIPPED_DBC)
    cro, dto = db.get_message_by_name("XCP_CRO"), db.get_message_by_name("XCP_DTO")
    assert (cro.frame_id, cro.length, dto.frame_id, dto.length) == (desc.cro_id, desc.max_cto, desc.dto_id, desc.max_dto)
    load = bus_load(ecu_desc.SHIPPED_DBC)
    per_tick = sum(wire_time_us(frame_bits(n, fd=True, brs=True), 500000, 4000000) for n in (desc.max_cto, desc.max_dto))
    assert abs(load.worst_pct - 100 * per_tick / desc.tick_us) < 1e-9


def test_the_xcp_identifiers_are_apart_from_every_dbc_frame():
    desc = xcp_ecu.description()
    ids = {m.frame_id for p in dbc_dir().glob("vehest_*.dbc") for m in cantools.database.load_file(p).messages}
    assert desc.cro_id not in ids and desc.dto_id not in ids


def test_busload_counts_the_xcp_bus_and_every_bus_is_within_60_percent(capsys):
    paths = [str(p) for p in sorted(dbc_dir().glob("vehest_*.dbc"))] + [str(ecu_desc.SHIPPED_DBC)]
    assert main(["busload", *paths, "--json"]) == 0
    buses = {b["bus"]: b for b in json.loads(capsys.readouterr().out)["buses"]}
    assert set(buses) == {"vehest_pt", "vehest_ch", "vehest_xcp"}
    assert all(b["worst_pct"] <= 60.0 for b in buses.values()), {k: b["worst_pct"] for k, b in buses.items()}
    assert 55.0 < buses["vehest_xcp"]["worst_pct"] <= 60.0  # 58.1 %: the budget is spent on purpose


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
    assert "ECU tick, XCP 20-signal DAQ at 1 ms" in text
