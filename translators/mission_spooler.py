"""The ``mission_spooler`` translator (AS6009 Mission Spooler): spool, run and watch missions.

No I/O. A mission is a tree of tasks, each a list of JAUS messages the vehicle's spooler
sends to its own components in order. JAUS -> DDS:

* ReportMissionStatus -> ``SpoolerStatus`` (per scope: MISSION, TASK or MESSAGE)
* ReportStoredMissions, ReportMissionPlan, ReportSpoolingPreferences -> ``SpoolerMissions``
  (the missions held, the plan of the last one read back with each carried message decoded,
  and the spooling preference)

DDS -> JAUS (``MissionSpoolCommand`` by ``action``; behind control and throttled by the
engine, one throttle slot per action so a SPOOL is never coalesced away by the RUN after
it): SpoolMission, RunMission, PauseMission, ResumeMission, AbortMission,
InsertMessages, RemoveMessages, InsertMissionTask, RemoveMissionTask, QueryMissionPlan.
Each message of a task is given by name with its fields as JSON and encoded with the
relay's catalogue; a message that does not encode refuses the whole command.

The service's protocol (the JSIDL) lets only the controlling client spool and change a
mission, and each order only in some states: SPOOL when no mission is held (INIT,
ABORTED, FINISHED), RUN when one is held or PAUSED (INIT, PAUSED), PAUSE while RUNNING,
RESUME and the Insert/Remove orders while PAUSED; ABORT and QUERY_PLAN at any time. INIT
is both "nothing held" and "held, not run" in ReportMissionStatus, so it allows both. An
order the last reported mission state does not allow is refused here, with the reason,
as ``SpoolerStatus`` scope ``COMMAND`` status ``REFUSED``; the vehicle would ignore it
silently.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping
from typing import Any

from edge_vis.kit import (
    Action,
    Build,
    Computed,
    DecodeError,
    Each,
    EncodeError,
    From,
    JausAddress,
    Publish,
    Put,
    ReportRule,
    RuleTranslator,
    TranslatorContext,
    follow_up_query,
    label,
    number,
)
from edge_vis.kit import CommandRule as Cmd

log = logging.getLogger(__name__)

SPOOLER = "urn:jaus:jss:missionSpooler:MissionSpooler"
#: ReportMissionStatus enumerations
SCOPES = {0: "MISSION", 1: "TASK", 2: "MESSAGE"}
STATUSES = {0: "INIT", 1: "RUNNING", 2: "PAUSING", 3: "PAUSED", 4: "ABORTING", 5: "ABORTED",
            6: "BLOCKED", 7: "FINISHED"}
DETAILS = {0: "NONE", 1: "LOST_COMPONENT_CONTROL", 2: "TOLERANCE_NOT_MET",
           3: "INTERNAL_FAILURE"}
#: action -> the mission states (last ReportMissionStatus) it is accepted in; absent: any
ALLOWED_IN = {
    "SPOOL": ("INIT", "ABORTED", "FINISHED"),
    "RUN": ("INIT", "PAUSED"),
    "PAUSE": ("RUNNING",),
    "RESUME": ("PAUSED",),
    "INSERT_MESSAGES": ("PAUSED",),
    "REMOVE_MESSAGES": ("PAUSED",),
    "INSERT_TASK": ("PAUSED",),
    "REMOVE_TASK": ("PAUSED",),
}
#: mission plans read back unasked when new missions appear in ReportStoredMissions
PLANS_ASKED_PER_CHANGE = 4
#: seconds a spooler order may wait for control before it is dropped
ORDER_LIFESPAN = 5.0


def action_of(value: Any) -> str:
    """The action of a sample, without the IDL prefix (``SPOOLER_RUN`` -> ``RUN``)."""
    text = str(value or "").strip().upper()
    return text.removeprefix("SPOOLER_")


def address_bits(address: JausAddress) -> dict[str, int]:
    """A JAUS address as the spooler messages' ID bit field."""
    return {"subsystem_id": address.subsystem, "node_id": address.node,
            "component_id": address.component}


def address_text(bits: Any) -> str:
    """``S.N.C`` of an ID bit field."""
    if not isinstance(bits, Mapping):
        return ""
    return f"{bits.get('subsystem_id', 0)}.{bits.get('node_id', 0)}.{bits.get('component_id', 0)}"


def _optional(member: str) -> Put:
    return Put(member, 0, 0xFFFF, convert=int, optional=True, note="0 = left out")


def _uids(member: str) -> Build:
    return Build("uids", lambda s: [{member: int(u)} for u in s.get("uids") or ()],
                 f"one {member} per uid")


def _messages(sample: Mapping[str, Any]) -> list[dict[str, Any]]:
    tasks = sample.get("_tasks") or []
    if not tasks:
        raise ValueError("no task given")
    return list(tasks[0]["task_data"]["jaus_messages"])


def _task(sample: Mapping[str, Any]) -> dict[str, Any]:
    tasks = sample.get("_tasks") or []
    if not tasks:
        raise ValueError("no task given")
    task = tasks[0]
    return {"task_data": {"task_info": task["task_data"]["task_info"],
                          "task_messages": task["task_data"]["jaus_messages"]},
            "sub_tasks": task["sub_tasks"]}


def _cmd(action: str, message: str, fields: Mapping[str, Any], doc: str = "") -> Cmd:
    return Cmd("MissionSpoolCommand", message, SPOOLER, f"spooler_{action.lower()}",
               dict(fields), when={"action": (action, f"SPOOLER_{action}")}, doc=doc,
               lifespan=ORDER_LIFESPAN)


_MISSION = Build("mission_id", lambda s: int(s.get("mission_id") or 0), "")
_TASK = Build("task_id", lambda s: int(s.get("task_id") or 0), "")
_WHERE = Build("after", lambda s: 1 if s.get("after") else 0, "0 before, 1 after")

COMMAND_RULES = (
    _cmd("SPOOL", "SpoolMission", {
        "mission_info.mission_id": _MISSION,
        "mission_info.source_id": Build("(relay)", lambda s: s["_relay"],
                                        "the relay's JAUS address"),
        "mission_plan": Build("tasks", lambda s: s["_tasks"],
                              "task_id, messages[] (name + fields_json, encoded), "
                              "child_tasks[]")},
         "only the controlling client; the spooler holds it until RUN"),
    _cmd("RUN", "RunMission", {"mission_id": _MISSION, "task_id": _optional("task_id"),
                               "message_uid": _optional("message_uid")},
         "from the start, or from task_id / message_uid"),
    _cmd("PAUSE", "PauseMission", {"mission_id": _MISSION, "task_id": _optional("task_id")},
         "while RUNNING"),
    _cmd("RESUME", "ResumeMission", {"mission_id": _MISSION}, "while PAUSED"),
    _cmd("ABORT", "AbortMission", {"mission_id": _MISSION}, "in any state"),
    _cmd("INSERT_MESSAGES", "InsertMessages", {
        "mission_and_task_info.mission_id": _MISSION,
        "mission_and_task_info.task_id": _TASK,
        "mission_and_task_info.uid": Build("message_uid",
                                           lambda s: int(s.get("message_uid") or 0), ""),
        "mission_and_task_info.insert_location": _WHERE,
        "insert_message_list": Build("tasks[0].messages", _messages, "encoded")},
         "while PAUSED"),
    _cmd("REMOVE_MESSAGES", "RemoveMessages", {
        "mission_info.mission_id": _MISSION, "mission_info.task_id": _TASK,
        "message_list": _uids("uid")}, "while PAUSED"),
    _cmd("INSERT_TASK", "InsertMissionTask", {
        "mission_and_task_info.mission_id": _MISSION,
        "mission_and_task_info.task_id": _TASK,
        "mission_and_task_info.insert_location": _WHERE,
        "mission_and_task_info.new_parent_task_id": Build(
            "parent_task_id", lambda s: int(s.get("parent_task_id") or 0), ""),
        "task": Build("tasks[0]", _task, "encoded")}, "while PAUSED"),
    _cmd("REMOVE_TASK", "RemoveMissionTask", {
        "mission_and_task_info.mission_id": _MISSION,
        "mission_and_task_info.task_id": _TASK,
        "remove_task_list": _uids("task_id")}, "while PAUSED"),
    _cmd("QUERY_PLAN", "QueryMissionPlan", {"mission_id": _MISSION},
         "the answer goes to SpoolerMissions"),
)


def _decoded_plan(fields: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The MissionTask of a ReportMissionPlan whose messages were decoded beforehand."""
    task = fields.get("task") or {}
    data = task.get("task_data") or {}
    return [{"task_id": int((data.get("task_info") or {}).get("task_id", 0)),
             "messages": list(data.get("jaus_messages") or ()),
             "child_tasks": [int(c.get("child_task_index", 0))
                             for c in task.get("sub_tasks") or ()]}]


REPORT_RULES = (
    ReportRule("ReportMissionStatus", "SpoolerStatus",
               {"scope": From("type", convert=label(SCOPES)), "id": From("id", default=0),
                "status": From("status", convert=label(STATUSES)),
                "detail": From("secondary_status", convert=label(DETAILS))},
               query="QueryMissionStatus", service=SPOOLER, rate=1.0, on_change=True,
               doc="the running (or last) mission; every-change event"),
    ReportRule("ReportStoredMissions", "SpoolerMissions",
               {"missions": Each("mission_list", {
                   "mission_id": From("mission_id", default=0),
                   "creator": From("creator_id", convert=address_text, default="")})},
               query="QueryStoredMissions", service=SPOOLER, rate=0.2, on_change=True,
               merge=True, doc="a new mission's plan is read back with QueryMissionPlan"),
    ReportRule("ReportMissionPlan", "SpoolerMissions",
               {"plan_mission_id": From("mission_info.mission_id", default=-1),
                "plan_source": From("mission_info.source_id", convert=address_text,
                                    default=""),
                "plan": Computed(_decoded_plan, "task: task_id, jaus_messages[] decoded to "
                                                "name + fields_json, sub_tasks[]")},
               merge=True, doc="asked for by QUERY_PLAN and for each new stored mission"),
    ReportRule("ReportSpoolingPreferences", "SpoolerMissions",
               {"preference": From("data.*", convert=number)},
               query="QuerySpoolingPreferences", service=SPOOLER, rate=0.1, on_change=True,
               merge=True, doc="the variant's value, whichever alternative"),
)


class MissionSpoolerTranslator(RuleTranslator):
    """Mission Spooler <-> ``MissionSpoolCommand``, ``SpoolerStatus``, ``SpoolerMissions``.

    The rules are tables; around them this class encodes the JAUS messages of a mission's
    tasks (and decodes those of a plan read back) with the context's catalogue, refuses
    orders the mission's state does not allow, and asks for the plan of new missions.
    """

    name = "mission_spooler"
    report_rules = REPORT_RULES
    command_rules = COMMAND_RULES
    extra_publishes = ("SpoolerStatus",)

    def __init__(self) -> None:
        super().__init__()
        #: vehicle -> last mission status reported (MISSION scope)
        self.state: dict[str, str] = {}
        #: vehicle -> mission IDs whose plan was asked for
        self.planned: dict[str, set[int]] = {}

    def on_message(self, name: str, fields: Mapping[str, Any],
                   ctx: TranslatorContext) -> list[Action]:
        if ctx.vehicle is None:
            return []
        vehicle_id = ctx.vehicle.vehicle_id
        if name == "ReportMissionPlan":
            fields = self._decode_plan(fields, ctx)
        actions = super().on_message(name, fields, ctx)
        if name == "ReportMissionStatus" and fields.get("type") == 0:
            self.state[vehicle_id] = label(STATUSES)(fields.get("status"))
        if name == "ReportStoredMissions" and ctx.source is not None:
            held = {int(m.get("mission_id", 0)) for m in fields.get("mission_list") or ()}
            asked = self.planned.setdefault(vehicle_id, set())
            asked &= held  # a mission removed and spooled again is read again
            for mission_id in sorted(held - asked)[:PLANS_ASKED_PER_CHANGE]:
                asked.add(mission_id)
                actions.append(follow_up_query(ctx.source, "QueryMissionPlan",
                                               {"mission_id": mission_id}))
        return actions

    def on_sample(self, topic: str, sample: Mapping[str, Any],
                  ctx: TranslatorContext) -> list[Action]:
        vehicle = ctx.vehicle
        if vehicle is None:
            return []
        action = action_of(sample.get("action"))
        state = self.state.get(vehicle.vehicle_id)
        allowed = ALLOWED_IN.get(action)
        if allowed is not None and state is not None and state not in allowed:
            return [self._refuse(vehicle.vehicle_id, sample, ctx,
                                 f"{action} refused: the mission is {state} "
                                 f"({action} is accepted when {' or '.join(allowed)})")]
        try:
            tasks = [self._task(task, vehicle, ctx) for task in sample.get("tasks") or ()]
        except (ValueError, EncodeError) as exc:
            return [self._refuse(vehicle.vehicle_id, sample, ctx, f"{action} refused: {exc}")]
        if action == "SPOOL" and not tasks:
            return [self._refuse(vehicle.vehicle_id, sample, ctx,
                                 "SPOOL refused: the mission has no task")]
        if action == "SPOOL":
            # a new mission: what the last one's state allowed no longer says anything
            self.state.pop(vehicle.vehicle_id, None)
        prepared = {**sample, "_tasks": tasks, "_relay": address_bits(ctx.relay_id),
                    # an ID of 0 narrows nothing: left out of RunMission / PauseMission
                    "task_id": sample.get("task_id") or None,
                    "message_uid": sample.get("message_uid") or None}
        return super().on_sample(topic, prepared, ctx)

    # -- encoding and decoding the carried messages ------------------------------------

    @staticmethod
    def _task(task: Mapping[str, Any], vehicle: Any, ctx: TranslatorContext) -> dict[str, Any]:
        task_id = int(task.get("task_id", 0))
        spooler = next((a for a, services in vehicle.components.items()
                        if any(uri == SPOOLER for uri, _ in services)), vehicle.address)
        messages = []
        for message in task.get("messages") or ():
            where = f"task {task_id} message {message.get('uid', 0)}"
            name = str(message.get("message", ""))
            try:
                fields = json.loads(str(message.get("fields_json") or "{}"))
            except json.JSONDecodeError as exc:
                raise ValueError(f"{where}: fields_json is not JSON ({exc.msg})") from None
            if not isinstance(fields, dict):
                raise ValueError(f"{where}: fields_json is not a JSON object")
            try:
                payload = ctx.catalogue.encode(name, fields)
            except (EncodeError, KeyError) as exc:
                raise ValueError(f"{where}: {name or '(no name)'} does not encode: "
                                 f"{exc}") from None
            target = str(message.get("destination") or "")
            try:
                destination = JausAddress.parse(target) if target else spooler
            except ValueError as exc:
                raise ValueError(f"{where}: {exc}") from None
            if destination is None:
                raise ValueError(f"{where}: no destination and no spooler component")
            messages.append({"uid": int(message.get("uid", 0)),
                             "destination_id": address_bits(destination),
                             "jaus_message": payload,
                             "blocking": 1 if message.get("blocking") else 0})
        return {"task_data": {"task_info": {"task_id": task_id}, "jaus_messages": messages},
                "sub_tasks": [{"child_task_index": int(c)}
                              for c in task.get("child_tasks") or ()]}

    @staticmethod
    def _decode_plan(fields: Mapping[str, Any], ctx: TranslatorContext) -> dict[str, Any]:
        task = dict(fields.get("task") or {})
        data = dict(task.get("task_data") or {})
        decoded = []
        for message in data.get("jaus_messages") or ():
            name, inner = "", {}
            try:
                found = ctx.catalogue.decode(bytes(message.get("jaus_message") or b""))
                name, inner = found.name or "", found.fields or {}
            except DecodeError as exc:  # shown without its content
                log.debug("mission plan message not decoded: %s", exc)
            decoded.append({"uid": int(message.get("uid", 0)), "message": name,
                            "fields_json": json.dumps(inner, default=_jsonable),
                            "destination": address_text(message.get("destination_id")),
                            "blocking": bool(message.get("blocking"))})
        data["jaus_messages"] = decoded
        task["task_data"] = data
        return {**fields, "task": task}

    @staticmethod
    def _refuse(vehicle_id: str, sample: Mapping[str, Any], ctx: TranslatorContext,
                why: str) -> Publish:
        log.warning("MissionSpoolCommand for %s from %s: %s", vehicle_id,
                    sample.get("operator_id"), why)
        return Publish("SpoolerStatus", {
            "vehicle_id": vehicle_id, "scope": "COMMAND",
            "id": int(sample.get("mission_id") or 0), "status": "REFUSED", "detail": why,
            "timestamp_ms": ctx.timestamp_ms})


def _jsonable(value: Any) -> Any:
    """JSON for what a decoded message may hold besides numbers and text."""
    if isinstance(value, bytes | bytearray):
        return value.hex()
    return str(value)
