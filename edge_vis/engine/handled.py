"""The JAUS messages the engine itself sends and handles, declared once. No I/O.

Translators map reports and commands; discovery, access control, events, liveness, time
and the emergency stop are the engine's own (AS5710A core services), and so is the IOP
hand-off between operators (EnhancedAccessControl, HandoffController). ``edge-vis mappings``
counts these as *on the wire, handled by the engine* and a test checks the declaration
against the engine's code, so the table cannot claim a message the engine never uses.

:data:`ENGINE_DECLINED` lists the other core messages with the reason the relay, a client
of the vehicle's core services, has no use for them.
"""

from __future__ import annotations

from collections.abc import Mapping

#: messages the engine acts on when they arrive -> what it does with them
ENGINE_RECEIVES: Mapping[str, str] = {
    "ReportIdentification": "discovery: a subsystem and its name",
    "ReportConfiguration": "discovery: the subsystem's nodes and components",
    "ReportServices": "discovery: the services of each component",
    "ReportHeartbeatPulse": "liveness: an answer to the relay's pulse query",
    "ReportStatus": "readiness for commands; emergency stop confirmed",
    "ConfirmControl": "access control granted or refused",
    "RejectControl": "access control lost or released",
    "ReportTimeout": "how often control must be renewed",
    "ReportControl": "who holds each component",
    "ReportAuthority": "each component's current authority",
    "ReportTime": "the vehicle's clock against the relay's",
    "ConfirmEventRequest": "an event set up",
    "RejectEventRequest": "an event refused: the report is polled instead",
    "ReportEventTimeout": "how often events must be renewed",
    "Event": "carries a report: unwrapped and given to its translator",
    "RequestReleaseControl": "hand-off: another client asks for a vehicle an operator holds",
    "ConfirmHandoffRequest": "hand-off: the vehicle's answer to the relay's RequestHandoff",
    "ReportHandoffTimeout": "hand-off: how long requests through the vehicle stay open",
    "ReportEnhancedTimeout": "hand-off: the vehicle's re-assert timeout",
}

#: messages the engine sends on its own -> why
ENGINE_SENDS: Mapping[str, str] = {
    "QueryIdentification": "discovery and liveness of a silent vehicle",
    "QueryConfiguration": "discovery",
    "QueryServices": "discovery",
    "QueryHeartbeatPulse": "liveness",
    "QueryStatus": "readiness and emergency confirmation",
    "RequestControl": "control of the components an operator commands",
    "ReleaseControl": "control given back when the operator lets go",
    "QueryTimeout": "control renewal period",
    "QueryControl": "who holds each component",
    "QueryAuthority": "each component's authority",
    "SetAuthority": "the relay's authority while it holds control",
    "Standby": "a component held in STANDBY at the operator's request",
    "Resume": "a component made READY for commands",
    "QueryTime": "clock offset",
    "SetTime": "clock set, where the profile asks for it",
    "CreateEvent": "reports delivered as events",
    "UpdateEvent": "event rate changed by the bandwidth planner",
    "CancelEvent": "an event no longer wanted",
    "QueryEventTimeout": "event renewal period",
    "SetEmergency": "emergency stop",
    "ClearEmergency": "emergency stop cleared",
    "ConfirmReleaseControl": "hand-off: the holding operator's answer",
    "RequestHandoff": "hand-off: an operator asks for a vehicle another client holds",
    "RemoveHandoffRequest": "hand-off: that operator withdraws",
    "QueryHandoffTimeout": "hand-off timeout of a vehicle with EnhancedAccessControl",
    "QueryEnhancedTimeout": "re-assert timeout of a vehicle with EnhancedAccessControl",
}

#: every message the engine handles on the wire, either way
ENGINE_HANDLED: frozenset[str] = frozenset({*ENGINE_RECEIVES, *ENGINE_SENDS})

#: core messages the relay leaves alone -> why
ENGINE_DECLINED: Mapping[str, str] = {
    "QueryEvents": "the relay keeps its own list of the events it set up",
    "ReportEvents": "answer to QueryEvents, which the relay does not send",
    "QueryServiceList": "QueryServices gives the same services per component",
    "ReportServiceList": "answer to QueryServiceList, which the relay does not send",
    "RegisterServices": "the relay offers no services for others to discover",
    "QuerySubsystemList": "subsystems are found by broadcast QueryIdentification; a "
                          "system-wide Discovery list is optional and seldom offered",
    "ReportSubsystemList": "answer to QuerySubsystemList, which the relay does not send",
    "CreateCommandEvent": "commands go out as commands behind the relay's control; "
                          "command events are not used",
    "CommandEvent": "answer to CreateCommandEvent, which the relay does not send",
}
