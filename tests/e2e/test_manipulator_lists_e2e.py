"""A manipulator plan end to end: a real Cyclone DDS operator publishes a ManipulatorPlan,
the relay loads it into a manipulator's joint-position list over real UDP and executes it,
and the operator sees its progress and the list the manipulator holds.

The manipulator is a peer written here from the JSIDL (ManipulatorListDriver 2.0 over the
core List Manager 1.1): it only speaks the manipulator set, so a mobility ExecuteList or
QueryActiveElement (same names, other codes) would not even decode on its side, and its
ReportActiveElement is the manipulator's 0x461E."""

from __future__ import annotations

import asyncio
import time
from typing import Any

import pytest

from edge_vis.catalogue import Catalogue, default_catalogue
from edge_vis.jaus.address import JausAddress
from edge_vis.shell.relay import Runtime

from .peer_sets import SetPeer
from .test_translators_e2e import collect, relay_with, take_control, wait_for

pytestmark = pytest.mark.dds

MANIP = "urn:jaus:jss:manipulator:"
SERVICES = ("urn:jaus:jss:core:ListManager", MANIP + "ManipulatorListDriver",
            MANIP + "ManipulatorJointPositionListDriver", MANIP + "ManipulatorSpecificationService")
#: seconds the arm takes to reach each target
STEP = 0.8
#: RejectElementRequest response codes (ListManager 1.1)
INVALID_PREVIOUS, NOT_FOUND = 2, 5


def arm_catalogue() -> Catalogue:
    """Every shipped set but mobility's: the names are the manipulator's."""
    return Catalogue([d for d in default_catalogue() if d.service_set != "mobility"])


class ArmListPeer(SetPeer):
    """A manipulator whose joint-position list driver takes commands from its controller
    only: SetElement inserts linked elements (a previous UID it does not hold is refused),
    DeleteElement 65535 empties the list, ExecuteList goes through the elements one every
    :data:`STEP` seconds, reporting the active one (0 when done) at once to an every-change
    event, as well as periodically."""

    def __init__(self, address: JausAddress) -> None:
        super().__init__(address, SERVICES, {}, name="Arm", catalogue=arm_catalogue(),
                         version=(2, 0))
        self.elements: dict[int, dict[str, Any]] = {}
        self.active = 0
        self.changes = 0
        self.reports = {
            "QueryElementList": lambda f: ("ReportElementList", {"element_list": [
                {"element_uid": uid} for uid in self.order()]}),
            "QueryElementCount": lambda f: ("ReportElementCount",
                                            {"element_count": len(self.elements)}),
            "QueryElement": lambda f: ("ReportElement", self.elements[f["element_uid"]]),
            "QueryActiveElement": lambda f: ("ReportActiveElement",
                                             {"element_uid": self.active}),
        }

    def order(self) -> list[int]:
        heads = [u for u, e in self.elements.items() if e["previous_uid"] == 0]
        out: list[int] = []
        uid = heads[0] if heads else 0
        while uid in self.elements and uid not in out:
            out.append(uid)
            uid = self.elements[uid]["next_uid"]
        return out

    def handle(self, src: JausAddress, name: str | None, fields: dict[str, Any]) -> None:
        if name not in ("SetElement", "DeleteElement", "ExecuteList"):
            if name != "QueryElement" or fields.get("element_uid") in self.elements:
                super().handle(src, name, fields)
            return
        if src != self.controller:
            return
        if name == "ExecuteList":
            start = fields.get("element_uid") or (self.order() or [0])[0]
            if start in self.elements:
                self.active = start
                self._tasks.append(asyncio.get_running_loop().create_task(self._run()))
            return
        request_id = fields["request_id_rec"]["request_id"]
        code = 0
        if name == "DeleteElement":
            for rec in fields["delete_element_list"]:
                if rec["element_uid"] == 0xFFFF:
                    self.elements.clear()
                elif self.elements.pop(rec["element_uid"], None) is None:
                    code = NOT_FOUND
        else:
            for rec in fields["element_list"]:
                if rec["previous_uid"] and rec["previous_uid"] not in self.elements \
                        and rec["previous_uid"] not in {r["element_uid"]
                                                        for r in fields["element_list"]}:
                    code = INVALID_PREVIOUS
            if not code:
                self.elements.update({rec["element_uid"]: dict(rec)
                                      for rec in fields["element_list"]})
        if code:
            self.send(src, "RejectElementRequest", {"request_id": request_id,
                                                    "response_code": code})
        else:
            self.send(src, "ConfirmElementRequest", {"request_id": request_id})

    async def _run(self) -> None:
        self._active_changed()
        while self.active:
            await asyncio.sleep(STEP)
            self.active = self.elements[self.active]["next_uid"]
            self._active_changed()

    def _active_changed(self) -> None:
        """An every-change event fires when the active element changes, not only on the
        periodic tick."""
        for event_id, (dest, query, _fields, _rate) in self.events.items():
            if query == "QueryActiveElement":
                report = self.catalogue.encode("ReportActiveElement",
                                               {"element_uid": self.active})
                self.changes += 1
                self.send_payload(dest, self.catalogue.wrap_event(event_id, self.changes % 256,
                                                                  report))


def test_a_joint_position_plan_is_loaded_executed_and_read_back(domain_id: int,
                                                                partition: str) -> None:
    peer = ArmListPeer(JausAddress(88, 1, 3))
    vid = "Arm-88"
    targets = [{"values": [0.1 * i, -0.2 * i], "units": ["rad", "rad"]} for i in range(1, 4)]

    async def body(runtime: Runtime, operator: Any) -> None:
        await take_control(operator, peer, vid)
        assert operator.wait_for_subscribers("ManipulatorPlan", 1, 5.0)
        statuses = operator.reader("ManipulatorPlanStatus", depth=64)
        operator.publish("ManipulatorPlan", {"vehicle_id": vid, "operator_id": "op1",
                                             "plan_id": "pick", "mode": "joint_positions",
                                             "targets": targets})
        await wait_for(lambda: peer.names("ExecuteList"), 8, "ExecuteList")
        order = [r.name for r in peer.received
                 if r.name in ("DeleteElement", "SetElement", "ExecuteList")]
        assert order == ["DeleteElement", "SetElement", "ExecuteList"]
        (set_element,) = peer.names("SetElement")
        held = [peer.catalogue.decode(e["element_data"]["data"])
                for e in set_element.fields["element_list"]]
        assert {m.name for m in held} == {"SetJointPositions"}
        assert [j["joint_position"]["radian"] for m in held
                for j in m.fields["joint_position_list"]] == \
            pytest.approx([v for t in targets for v in t["values"]], abs=1e-3)
        # progress: the manipulator's ReportActiveElement reaches the manipulator translator
        seen: list[dict[str, Any]] = []
        deadline = time.monotonic() + 10.0
        while not any(s["state"] == "MISSION_COMPLETED" for s in seen):
            assert time.monotonic() < deadline, f"never completed: {seen}"
            seen += [s for s in await asyncio.to_thread(statuses.take, 0.2)
                     if s["vehicle_id"] == vid]
        progress = [(s["state"], s["active_target"]) for s in seen]
        assert progress[-1] == ("MISSION_COMPLETED", -1)
        executing = [active for state, active in progress if state == "MISSION_EXECUTING"]
        assert {0, 1, 2} <= set(executing) and executing == sorted(executing)
        assert {(s["plan_id"], s["target_count"]) for s in seen} == {("pick", 3)}
        # what the manipulator holds, read back element by element
        listed = await collect(operator, "ManipulatorList",
                               lambda s: s["vehicle_id"] == vid and s["complete"])
        assert listed["component"] == "88.1.3" and listed["element_count"] == 3
        assert [e["uid"] for e in listed["elements"]] == [1, 2, 3]
        assert [v for e in listed["elements"] for v in e["target"]["values"]] == \
            pytest.approx([v for t in targets for v in t["values"]], abs=1e-3)
        assert {e["message"] for e in listed["elements"]} == {"SetJointPositions"}

    asyncio.run(relay_with(peer, 251, domain_id, partition, body))
