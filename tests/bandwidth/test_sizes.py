"""Bytes on the link per report, computed from the catalogue's definitions."""

from __future__ import annotations

from edge_vis.bandwidth.demands import SizeSource, liveness_load, report_demand
from edge_vis.bandwidth.linkspec import LinkSpec
from edge_vis.bandwidth.sizes import packet_bytes, payload_size
from edge_vis.catalogue import default_catalogue
from edge_vis.config import from_mapping
from edge_vis.kit.contract import ReportSpec

CAT = default_catalogue()
SERIAL = LinkSpec(bit_rate=9600, bits_per_byte=10, overhead=18, mtu=256)


def test_requested_fields_decide_the_size() -> None:
    pose = CAT.by_name("ReportGlobalPose")
    everything = payload_size(pose, {"presence_vector": 0x1FF})
    position = payload_size(pose, {"presence_vector": 0x003})  # latitude, longitude
    assert position == 2 + 2 + 4 + 4   # code, presence vector, two u32
    assert everything > position
    # and the size is what the codec really produces with those fields present
    fields = {"latitude": 36.6, "longitude": -121.9}
    assert len(CAT.encode("ReportGlobalPose", fields)) == position


def test_event_and_poll_costs_include_header_and_framing() -> None:
    relay = from_mapping({})
    spec = ReportSpec("ReportGlobalPose", "QueryGlobalPose", "x",
                      {"presence_vector": 0x1FF}, 10.0)
    sizes = SizeSource(CAT)
    report = payload_size(CAT.by_name("ReportGlobalPose"), {"presence_vector": 0x1FF})
    event = report_demand("a", spec, relay, None, SERIAL, sizes)
    polled = report_demand("a", spec, relay, None, SERIAL, sizes, polled=True)
    assert event.report_bytes == report + 8 + 14 + 18  # Event wrapper, header, framing
    assert polled.report_bytes == report + 14 + 18
    assert polled.query_bytes == 4 + 14 + 18           # QueryGlobalPose: code + u16
    assert event.minimum == 1.0 and event.priority == 5  # defaults: a tenth, priority 5


def test_fragments_pay_the_header_each_and_liveness_scales_with_components() -> None:
    assert packet_bytes(600, 18, 256) == 600 + 3 * (14 + 18)
    relay = from_mapping({})
    one = liveness_load("a", relay, SERIAL, 1)
    three = liveness_load("a", relay, SERIAL, 3)
    assert three.outbound > 2.5 * one.outbound - 1 and three.inbound > one.inbound
