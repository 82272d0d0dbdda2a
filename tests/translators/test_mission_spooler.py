"""The mission_spooler translator: each MissionSpoolCommand action to its JAUS message
(table-driven, encoded by the catalogue), the reports to SpoolerStatus / SpoolerMissions,
and the orders the spooler's protocol does not allow in the reported state."""

from __future__ import annotations

import json
from dataclasses import replace
from typing import Any

import pytest
from rulekit import CAT, CTX, TYPES, check_report_rule

from edge_vis.dds.convert import converter_for
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.actions import Command, Publish, SendMessage
from translators.mission_spooler import SPOOLER, MissionSpoolerTranslator

SPOOLER_AT = JausAddress(150, 1, 4)
PAIRS = ((SPOOLER, "1.0"),)
SCTX = replace(CTX, vehicle=replace(CTX.vehicle, services=PAIRS,
                                    components={SPOOLER_AT: PAIRS}), source=SPOOLER_AT)

WAYPOINT = {"uid": 1, "message": "SetGlobalWaypoint",
            "fields_json": json.dumps({"latitude": 28.5, "longitude": -81.25}),
            "destination": "150.1.2", "blocking": True}
SPEED = {"uid": 2, "message": "SetTravelSpeed", "fields_json": json.dumps({"speed": 2.0})}


def order(action: str, **extra: Any) -> dict[str, Any]:
    sample = {"vehicle_id": "veh1", "operator_id": "op1", "action": action, "mission_id": 7,
              **extra}
    converter_for(TYPES["MissionSpoolCommand"]).to_struct(sample, "MissionSpoolCommand")
    return sample


def sent(tr: MissionSpoolerTranslator, sample: dict[str, Any]) -> Command:
    (command,) = tr.on_sample("MissionSpoolCommand", sample, SCTX)
    assert isinstance(command, Command)
    assert command.service == SPOOLER and command.operator_id == "op1"
    assert command.stop is None  # an order, not a motion command
    return command


def wire(command: Command) -> dict[str, Any]:
    """The command as the vehicle decodes it."""
    return CAT.decode(CAT.encode(command.name, command.fields)).fields


TASKS = [{"task_id": 10, "messages": [WAYPOINT, SPEED], "child_tasks": [1]},
         {"task_id": 11, "messages": [], "child_tasks": []}]

#: action, extra sample members, JAUS message, expected decoded fields (subset)
ORDERS = [
    ("SPOOL", {"tasks": TASKS}, "SpoolMission",
     {"mission_info": {"mission_id": 7, "source_id": {"component_id": 1, "node_id": 1,
                                                     "subsystem_id": 42}}}),
    ("RUN", {}, "RunMission", {"mission_id": 7}),
    ("SPOOLER_RUN", {"task_id": 11, "message_uid": 3}, "RunMission",
     {"mission_id": 7, "task_id": 11, "message_uid": 3}),
    ("PAUSE", {}, "PauseMission", {"mission_id": 7}),
    ("PAUSE", {"task_id": 10}, "PauseMission", {"mission_id": 7, "task_id": 10}),
    ("RESUME", {}, "ResumeMission", {"mission_id": 7}),
    ("ABORT", {}, "AbortMission", {"mission_id": 7}),
    ("REMOVE_MESSAGES", {"task_id": 10, "uids": [1, 2]}, "RemoveMessages",
     {"mission_info": {"mission_id": 7, "task_id": 10},
      "message_list": [{"uid": 1}, {"uid": 2}]}),
    ("INSERT_MESSAGES", {"task_id": 10, "message_uid": 1, "after": True,
                         "tasks": [{"task_id": 10, "messages": [SPEED]}]}, "InsertMessages",
     {"mission_and_task_info": {"mission_id": 7, "task_id": 10, "uid": 1,
                                "insert_location": 1}}),
    ("INSERT_TASK", {"task_id": 10, "parent_task_id": 10,
                     "tasks": [{"task_id": 12, "messages": [WAYPOINT]}]}, "InsertMissionTask",
     {"mission_and_task_info": {"mission_id": 7, "task_id": 10, "insert_location": 0,
                                "new_parent_task_id": 10}}),
    ("REMOVE_TASK", {"task_id": 10, "uids": [11]}, "RemoveMissionTask",
     {"mission_and_task_info": {"mission_id": 7, "task_id": 10},
      "remove_task_list": [{"task_id": 11}]}),
    ("QUERY_PLAN", {}, "QueryMissionPlan", {"mission_id": 7}),
]


@pytest.mark.parametrize(("action", "extra", "message", "expected"), ORDERS,
                         ids=[f"{a}-{m}-{i}" for i, (a, _, m, _) in enumerate(ORDERS)])
def test_each_order_becomes_its_message(action: str, extra: dict[str, Any], message: str,
                                        expected: dict[str, Any]) -> None:
    command = sent(MissionSpoolerTranslator(), order(action, **extra))
    assert command.name == message
    got = wire(command)
    for key, value in expected.items():
        assert got[key] == value, key
    if action in ("RUN", "PAUSE") and not extra:
        assert "task_id" not in got and "message_uid" not in got  # 0 = left out


def test_spooled_tasks_carry_the_encoded_messages() -> None:
    command = sent(MissionSpoolerTranslator(), order("SPOOL", tasks=TASKS))
    first, second = wire(command)["mission_plan"]
    assert first["task_data"]["task_info"]["task_id"] == 10
    assert [c["child_task_index"] for c in first["sub_tasks"]] == [1]
    waypoint, speed = first["task_data"]["jaus_messages"]
    assert waypoint["destination_id"] == {"component_id": 2, "node_id": 1, "subsystem_id": 150}
    assert waypoint["blocking"] == 1 and speed["blocking"] == 0
    inner = CAT.decode(waypoint["jaus_message"])
    assert inner.name == "SetGlobalWaypoint"
    assert inner.fields["latitude"] == pytest.approx(28.5, abs=1e-6)
    # no destination: the spooler's own component
    assert speed["destination_id"] == {"component_id": 4, "node_id": 1, "subsystem_id": 150}
    assert CAT.decode(speed["jaus_message"]).fields["speed"] == pytest.approx(2.0, abs=0.01)
    assert second["task_data"]["jaus_messages"] == []
    # each action has its own throttle slot: a RUN right after never replaces the SPOOL
    run = sent(MissionSpoolerTranslator(), order("RUN"))
    assert run.kind != command.kind


@pytest.mark.parametrize(("message", "why"), [
    ({"uid": 1, "message": "NoSuchMessage", "fields_json": "{}"}, "NoSuchMessage"),
    ({"uid": 1, "message": "SetTravelSpeed", "fields_json": "{speed: 1"}, "not JSON"),
    ({"uid": 1, "message": "SetTravelSpeed", "fields_json": "[1]"}, "not a JSON object"),
    ({"uid": 1, "message": "SetTravelSpeed", "fields_json": "{}"}, "does not encode"),
    ({"uid": 1, "message": "SetTravelSpeed", "fields_json": "{\"speed\": 1}",
      "destination": "1.2"}, "S.N.C"),
])
def test_a_message_that_does_not_encode_refuses_the_order(message: dict[str, Any],
                                                          why: str) -> None:
    out = MissionSpoolerTranslator().on_sample(
        "MissionSpoolCommand", order("SPOOL", tasks=[{"task_id": 1, "messages": [message]}]),
        SCTX)
    (refusal,) = out
    assert isinstance(refusal, Publish) and refusal.topic == "SpoolerStatus"
    assert refusal.sample["status"] == "REFUSED" and refusal.sample["scope"] == "COMMAND"
    assert why in refusal.sample["detail"] and "task 1 message 1" in refusal.sample["detail"]
    converter_for(TYPES["SpoolerStatus"]).to_struct(dict(refusal.sample), "SpoolerStatus")


def test_spooling_nothing_is_refused() -> None:
    (refusal,) = MissionSpoolerTranslator().on_sample("MissionSpoolCommand", order("SPOOL"),
                                                      SCTX)
    assert "no task" in refusal.sample["detail"]


def status(tr: MissionSpoolerTranslator, state: int, scope: int = 0) -> list[Any]:
    fields = {"type": scope, "id": 7, "status": state, "secondary_status": 0}
    return tr.on_message("ReportMissionStatus", CAT.decode(CAT.encode(
        "ReportMissionStatus", fields)).fields, SCTX)


#: reported mission state, actions refused in it, actions sent in it
PROTOCOL = [
    (1, ("RESUME", "INSERT_MESSAGES", "REMOVE_TASK", "RUN", "SPOOL"),
     ("PAUSE", "ABORT", "QUERY_PLAN")),
    (3, ("PAUSE", "SPOOL"), ("RESUME", "REMOVE_MESSAGES", "REMOVE_TASK", "ABORT", "RUN")),
    (0, ("PAUSE", "RESUME"), ("RUN", "ABORT", "SPOOL")),
    (7, ("RUN", "PAUSE", "INSERT_TASK"), ("ABORT", "QUERY_PLAN", "SPOOL")),
]


@pytest.mark.parametrize(("state", "refused", "allowed"), PROTOCOL)
def test_orders_follow_the_spoolers_protocol(state: int, refused: tuple[str, ...],
                                             allowed: tuple[str, ...]) -> None:
    tr = MissionSpoolerTranslator()
    status(tr, state)
    extra = {"tasks": TASKS, "task_id": 10, "uids": [1]}
    for action in refused:
        (out,) = tr.on_sample("MissionSpoolCommand", order(action, **extra), SCTX)
        assert isinstance(out, Publish) and out.sample["status"] == "REFUSED", action
        assert action in out.sample["detail"]
    for action in allowed:
        (out,) = tr.on_sample("MissionSpoolCommand", order(action, **extra), SCTX)
        assert isinstance(out, Command), action
    # a task's status does not change what the mission accepts
    status(tr, 3, scope=1)
    assert isinstance(tr.on_sample("MissionSpoolCommand", order(allowed[0], **extra),
                                   SCTX)[0], Command)


def test_a_new_mission_may_be_run_before_its_state_is_reported() -> None:
    tr = MissionSpoolerTranslator()
    status(tr, 7)  # the last mission finished
    assert sent(tr, order("SPOOL", mission_id=8, tasks=TASKS)).name == "SpoolMission"
    assert sent(tr, order("RUN", mission_id=8)).name == "RunMission"


def test_status_reports_are_named() -> None:
    (pub,) = status(MissionSpoolerTranslator(), 6)
    assert pub.topic == "SpoolerStatus"
    assert (pub.sample["scope"], pub.sample["id"], pub.sample["status"]) == (
        "MISSION", 7, "BLOCKED")
    assert pub.sample["detail"] == "NONE"


def test_stored_missions_read_back_new_plans_and_merge() -> None:
    tr = MissionSpoolerTranslator()
    stored = {"mission_list": [{"mission_id": m, "creator_id": {
        "subsystem_id": 42, "node_id": 1, "component_id": 1}} for m in (7, 8)]}
    out = tr.on_message("ReportStoredMissions", stored, SCTX)
    assert [(a.name, a.fields["mission_id"], a.destination) for a in out
            if isinstance(a, SendMessage)] == [("QueryMissionPlan", 7, SPOOLER_AT),
                                               ("QueryMissionPlan", 8, SPOOLER_AT)]
    # the same missions again: nothing more to read
    assert not [a for a in tr.on_message("ReportStoredMissions", stored, SCTX)
                if isinstance(a, SendMessage)]
    plan = {"mission_info": {"mission_id": 7, "source_id": {
        "subsystem_id": 42, "node_id": 1, "component_id": 1}},
        "task": {"task_data": {"task_info": {"task_id": 10}, "jaus_messages": [
            {"uid": 1, "destination_id": {"subsystem_id": 150, "node_id": 1,
                                          "component_id": 2},
             "jaus_message": CAT.encode("SetTravelSpeed", {"speed": 2.0}), "blocking": 1},
            {"uid": 2, "destination_id": {"subsystem_id": 150, "node_id": 1,
                                          "component_id": 2},
             "jaus_message": b"\xff\xff\x01", "blocking": 0}]},
            "sub_tasks": [{"child_task_index": 1}]}}
    fields = CAT.decode(CAT.encode("ReportMissionPlan", plan)).fields
    (pub,) = tr.on_message("ReportMissionPlan", fields, SCTX)
    sample = dict(pub.sample)
    converter_for(TYPES["SpoolerMissions"]).to_struct(sample, "SpoolerMissions")
    assert [m["mission_id"] for m in sample["missions"]] == [7, 8]  # merged, kept
    assert sample["missions"][0]["creator"] == "42.1.1"
    assert (sample["plan_mission_id"], sample["plan_source"]) == (7, "42.1.1")
    (task,) = sample["plan"]
    assert task["task_id"] == 10 and task["child_tasks"] == [1]
    known, unknown = task["messages"]
    assert known["message"] == "SetTravelSpeed" and known["destination"] == "150.1.2"
    assert json.loads(known["fields_json"])["speed"] == pytest.approx(2.0, abs=0.01)
    assert known["blocking"] is True
    assert unknown["message"] == "" and not unknown["blocking"]
    # a mission removed and spooled again is read again
    tr.on_message("ReportStoredMissions", {"mission_list": []}, SCTX)
    again = tr.on_message("ReportStoredMissions", stored, SCTX)
    assert len([a for a in again if isinstance(a, SendMessage)]) == 2


@pytest.mark.parametrize("rule", [r for r in MissionSpoolerTranslator.report_rules
                                  if r.message != "ReportMissionPlan"],
                         ids=lambda r: r.message)
def test_report_rules_on_random_reports(rule: Any) -> None:
    assert check_report_rule(MissionSpoolerTranslator(), rule) > 0
