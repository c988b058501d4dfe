"""The description: layout, limits through the conversion, and what it refuses."""
import pytest
from xcp_demo import DEMO, Slave, XcpConfigError  # noqa: E402

from vehest_can.xcp import DescriptionError, load
from vehest_can.xcp.description import from_dict


def test_demo_layout_is_c_aligned_and_inside_its_segments():
    d = load(DEMO)
    assert len(d.measurements) == 23 and len(d.characteristics) == 6
    for it in d.measurements + d.characteristics:
        assert it.address % it.element_size == 0
    g = d.item("skf_gain")
    assert g.count == 16 and g.size == 64
    t = d.item("torque_offset")  # physical = 0.25 * raw: +-100 Nm is +-400 raw
    assert t.raw_limits() == (-400.0, 400.0) and t.compu_name == "CM_torque_offset"


def base(**kw):
    d = {"xcp": {}, "event": [{"name": "tick", "cycle_us": 500}],
         "measurement": [{"name": "a", "type": "float"}],
         "characteristic": [{"name": "k", "type": "float", "min": 0.0, "max": 1.0, "initial": 0.5}]}
    d.update(kw)
    return d


@pytest.mark.parametrize("change, msg", [
    ({"measurement": [{"name": "a", "type": "float128"}]}, "unknown C type"),
    ({"measurement": [{"name": "a", "type": "float"}, {"name": "a", "type": "float"}]}, "unique"),
    ({"measurement": [{"name": "a", "type": "float", "shape": [2]}]}, "scalars"),
    ({"measurement": [{"name": "a", "type": "float", "colour": "red"}]}, "unknown keys"),
    ({"characteristic": [{"name": "k", "type": "float", "min": 0.0, "max": 1.0, "initial": 2.0}]}, "outside"),
    ({"characteristic": [{"name": "k", "type": "float", "shape": [2], "initial": [1.0]}]}, "initial values"),
    ({"characteristic": [{"name": "k", "type": "uint8_t"}, {"name": "j", "type": "uint8_t", "address": 0x20000000}]},
     "overlaps"),
    ({"xcp": {"max_dto": 64}}, "CAN FD"),
    ({"event": [{"name": "odd", "cycle_us": 2555}]}, "no exact XCP cycle"),
])
def test_refused(change, msg):
    with pytest.raises(DescriptionError, match=msg):
        from_dict(base(**change))


def test_the_c_slave_refuses_what_it_cannot_serve():
    d = from_dict(base(xcp={"max_cto": 7}))
    with pytest.raises(XcpConfigError):
        Slave(d, key=bytes(16))
