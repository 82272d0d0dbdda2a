"""ComponentControl (the relay's AccessControl client) against its transition table.

The table is the one in :mod:`edge_vis.engine.control`, read against the AccessControl
protocol behaviour of core v1.1 (``jsidl/urn.jaus.jss.core-v1.1/AccessControl.xml``):

* a component answers RequestControl with ConfirmControl CONTROL_ACCEPTED (0),
  NOT_AVAILABLE (1) or INSUFFICIENT_AUTHORITY (2);
* the controlling client keeps control by re-sending RequestControl before the
  component's timeout (ReportTimeout, seconds, 0 = none), which resets its timer;
* control ends with RejectControl CONTROL_RELEASED (0) - after ReleaseControl, on the
  component's timeout, or when a higher authority takes over - or NOT_AVAILABLE (1).

Each row starts from a state reached by a scripted history (every step at t = 0), feeds
one input at a time of the fake clock, and asserts the next state, the exact messages the
relay sends (encoded through the catalogue, so field names count) and when the machine
next wants to act.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from itertools import pairwise
from typing import Any

import pytest

from edge_vis.config import ControlProfile
from edge_vis.engine.control import READY, ComponentControl, ControlState, Outgoing

from .conftest import SHARED, wire

PROFILE = ControlProfile(renewal_period=2.0, response_timeout=1.0, retry_period=5.0,
                         max_ready_attempts=2)
AUTHORITY = 100

# ConfirmControl / RejectControl response codes (AccessControl, core v1.1)
CONTROL_ACCEPTED, NOT_AVAILABLE, INSUFFICIENT_AUTHORITY = 0, 1, 2
CONTROL_RELEASED = 0

IDLE = ControlState.IDLE
REQUESTING = ControlState.REQUESTING
CONTROLLED = ControlState.CONTROLLED
REFUSED = ControlState.REFUSED
RELEASING = ControlState.RELEASING

REQUEST = ("RequestControl", {"authority_code": AUTHORITY})
RELEASE = ("ReleaseControl", {})
QUERY_TIMEOUT = ("QueryTimeout", {})
RESUME = ("Resume", {})
QUERY_STATUS = ("QueryStatus", {})

Input = tuple[Any, ...]


def feed(ctl: ComponentControl, event: Input, now: float) -> list[Outgoing]:
    """Apply one input to the machine; what it wants sent."""
    kind, *args = event
    if kind == "want":
        return ctl.want(args[0], now)
    if kind == "ConfirmControl":
        return ctl.on_confirm(args[0], now)
    if kind == "RejectControl":
        return ctl.on_reject(args[0], now)
    if kind == "ReportTimeout":
        ctl.on_timeout_report(args[0], now)
        return []
    if kind == "ReportStatus":
        return ctl.on_status(args[0], now)
    if kind == "timer":
        return ctl.poll(now)
    if kind == "lost":
        ctl.on_lost()
        return []
    if kind == "found":
        return ctl.on_found(now)
    raise AssertionError(f"unknown input {kind}")


def describe(event: Input) -> str:
    kind, *args = event
    return f"{kind}({', '.join(map(str, args))})" if args else kind


#: name -> (inputs that reach it, all at t = 0; the state they reach)
HISTORIES: dict[str, tuple[list[Input], ControlState]] = {
    "idle": ([], IDLE),
    "requesting": ([("want", True)], REQUESTING),
    "controlled": ([("want", True), ("ConfirmControl", CONTROL_ACCEPTED)], CONTROLLED),
    "controlled, timeout 10 s": ([("want", True), ("ConfirmControl", CONTROL_ACCEPTED),
                                  ("ReportTimeout", 10)], CONTROLLED),
    "refused": ([("want", True), ("ConfirmControl", INSUFFICIENT_AUTHORITY)], REFUSED),
    "releasing": ([("want", True), ("ConfirmControl", CONTROL_ACCEPTED), ("want", False)],
                  RELEASING),
    "lost while wanted": ([("want", True), ("ConfirmControl", CONTROL_ACCEPTED), ("lost",)],
                          IDLE),
}


def machine(history: str, managed: bool = False) -> ComponentControl:
    ctl = ComponentControl(PROFILE, AUTHORITY, managed)
    inputs, reached = HISTORIES[history]
    for event in inputs:
        feed(ctl, event, 0.0)
    assert ctl.state is reached, f"history {history!r} did not reach {reached}"
    return ctl



# (history, input, at) -> (next state, messages sent, next deadline)
TABLE = [
    # IDLE: only wanting control does something
    ("idle", ("want", True), 0.5, REQUESTING, [REQUEST], 1.5),
    ("idle", ("want", False), 0.5, IDLE, [], None),
    ("idle", ("ConfirmControl", CONTROL_ACCEPTED), 0.5, IDLE, [], None),
    ("idle", ("RejectControl", CONTROL_RELEASED), 0.5, IDLE, [], None),
    ("idle", ("timer",), 10.0, IDLE, [], None),
    ("idle", ("found",), 0.5, IDLE, [], None),
    # REQUESTING: RequestControl sent at 0, answer due by the response timeout (1 s)
    ("requesting", ("ConfirmControl", CONTROL_ACCEPTED), 0.5, CONTROLLED, [QUERY_TIMEOUT], 2.5),
    ("requesting", ("ConfirmControl", NOT_AVAILABLE), 0.5, REFUSED, [], 5.5),
    ("requesting", ("ConfirmControl", INSUFFICIENT_AUTHORITY), 0.5, REFUSED, [], 5.5),
    ("requesting", ("RejectControl", CONTROL_RELEASED), 0.5, REFUSED, [], 1.5),
    ("requesting", ("timer",), 0.5, REQUESTING, [], 1.0),
    ("requesting", ("timer",), 1.0, REQUESTING, [REQUEST], 2.0),
    ("requesting", ("want", True), 0.5, REQUESTING, [], 1.0),
    ("requesting", ("want", False), 0.5, RELEASING, [RELEASE], 1.5),
    ("requesting", ("ReportTimeout", 10), 0.5, REQUESTING, [], 1.0),
    ("requesting", ("lost",), 0.5, IDLE, [], None),
    # CONTROLLED, timeout not reported: renewed every renewal_period (2 s)
    ("controlled", ("timer",), 1.9, CONTROLLED, [], 2.0),
    ("controlled", ("timer",), 2.0, CONTROLLED, [REQUEST], 4.0),
    ("controlled", ("ConfirmControl", CONTROL_ACCEPTED), 1.0, CONTROLLED, [], 3.0),
    ("controlled", ("ConfirmControl", NOT_AVAILABLE), 1.0, REFUSED, [], 6.0),
    ("controlled", ("ConfirmControl", INSUFFICIENT_AUTHORITY), 1.0, REFUSED, [], 6.0),
    ("controlled", ("RejectControl", CONTROL_RELEASED), 1.0, REFUSED, [], 2.0),
    ("controlled", ("RejectControl", NOT_AVAILABLE), 1.0, REFUSED, [], 2.0),
    ("controlled", ("ReportTimeout", 10), 1.0, CONTROLLED, [], 6.0),
    ("controlled", ("ReportTimeout", 0), 1.0, CONTROLLED, [], None),
    ("controlled", ("want", True), 1.0, CONTROLLED, [], 2.0),
    ("controlled", ("want", False), 1.0, RELEASING, [RELEASE], 2.0),
    ("controlled", ("lost",), 1.0, IDLE, [], None),
    # CONTROLLED, timeout 10 s reported: renewed at half of it
    ("controlled, timeout 10 s", ("timer",), 4.9, CONTROLLED, [], 5.0),
    ("controlled, timeout 10 s", ("timer",), 5.0, CONTROLLED, [REQUEST], 10.0),
    ("controlled, timeout 10 s", ("ConfirmControl", CONTROL_ACCEPTED), 5.0, CONTROLLED, [],
     10.0),
    # REFUSED: asked again after retry_period (5 s)
    ("refused", ("timer",), 4.9, REFUSED, [], 5.0),
    ("refused", ("timer",), 5.0, REQUESTING, [REQUEST], 6.0),
    ("refused", ("RejectControl", CONTROL_RELEASED), 1.0, REFUSED, [], 5.0),
    ("refused", ("want", False), 1.0, IDLE, [], None),  # never held: nothing to release
    ("refused", ("lost",), 1.0, IDLE, [], None),
    # RELEASING: ReleaseControl sent at 0; RejectControl or the response timeout ends it
    ("releasing", ("RejectControl", CONTROL_RELEASED), 0.5, IDLE, [], None),
    ("releasing", ("RejectControl", NOT_AVAILABLE), 0.5, IDLE, [], None),
    ("releasing", ("ConfirmControl", CONTROL_ACCEPTED), 0.5, RELEASING, [], 1.0),
    ("releasing", ("timer",), 0.5, RELEASING, [], 1.0),
    ("releasing", ("timer",), 1.0, IDLE, [], None),
    ("releasing", ("want", True), 0.5, REQUESTING, [REQUEST], 1.5),
    ("releasing", ("lost",), 0.5, IDLE, [], None),
    # lost while wanted: nothing until the vehicle is found again, then ask again
    ("lost while wanted", ("timer",), 3.0, IDLE, [], None),
    ("lost while wanted", ("found",), 3.0, REQUESTING, [REQUEST], 4.0),
]


@pytest.mark.parametrize(
    ("history", "event", "at", "state", "messages", "deadline"), TABLE,
    ids=[f"{row[0]}: {describe(row[1])} at {row[2]}" for row in TABLE],
)
def test_transition(catalogue: Any, history: str, event: Input, at: float,
                    state: ControlState, messages: list[tuple[str, dict[str, Any]]],
                    deadline: float | None) -> None:
    ctl = machine(history)
    out = feed(ctl, event, at)
    assert (ctl.state, wire(catalogue, out), ctl.next_deadline()) == (state, messages, deadline)


def test_every_state_and_input_kind_is_in_the_table() -> None:
    states = {HISTORIES[row[0]][1] for row in TABLE}
    assert states == set(ControlState)
    kinds = {row[1][0] for row in TABLE}
    assert kinds >= {"want", "ConfirmControl", "RejectControl", "ReportTimeout", "timer",
                     "lost", "found"}


@pytest.mark.parametrize("timeout", [1, 3, 10, 60, 255, None])
def test_control_is_renewed_before_the_component_times_out(timeout: int | None) -> None:
    """A component per the JSIDL: each RequestControl from its controller resets its timer;
    if the timer runs out it sends RejectControl(CONTROL_RELEASED). It answers after 0.1 s.
    ``None``: the component never answers QueryTimeout (renewal_period applies); its own
    timeout is then taken as the 3 s the JTS example uses."""
    limit = float(timeout) if timeout is not None else 3.0
    latency = 0.1
    ctl = machine("idle")
    now = 0.0
    sent_at: list[float] = []
    answers: list[tuple[float, Input]] = []

    def carry(out: list[Outgoing]) -> None:
        for item in out:
            if item.name == "RequestControl":
                sent_at.append(now)
                answers.append((now + latency, ("ConfirmControl", CONTROL_ACCEPTED)))
            elif item.name == "QueryTimeout" and timeout is not None:
                answers.append((now + latency, ("ReportTimeout", timeout)))

    carry(feed(ctl, ("want", True), now))
    end = 6 * limit
    while now < end:
        due = [t for t in (ctl.next_deadline(), *(t for t, _ in answers)) if t is not None]
        now = min(due)
        ready = [a for a in answers if a[0] <= now]
        answers = [a for a in answers if a[0] > now]
        for _t, event in ready:
            carry(feed(ctl, event, now))
        carry(ctl.poll(now))
        assert ctl.state is CONTROLLED or now < latency + 1e-9
    arrivals = [t + latency for t in sent_at]
    gaps = [b - a for a, b in pairwise(arrivals)]
    assert len(gaps) >= 5
    assert max(gaps) < limit  # every renewal reaches the component before its timer runs out


def test_no_renewal_when_the_component_never_times_out() -> None:
    ctl = machine("controlled")
    ctl.on_timeout_report(0, 0.0)
    assert ctl.next_deadline() is None
    assert ctl.poll(1000.0) == []
    assert ctl.state is CONTROLLED


def test_found_again_asks_control_and_its_timeout_afresh(catalogue: Any) -> None:
    ctl = machine("controlled, timeout 10 s")
    ctl.on_lost()
    assert wire(catalogue, ctl.on_found(20.0)) == [REQUEST]
    # the component may have restarted with another timeout: asked again
    assert wire(catalogue, ctl.on_confirm(CONTROL_ACCEPTED, 20.1)) == [QUERY_TIMEOUT]
    assert ctl.state is CONTROLLED


def test_release_answered_and_unanswered() -> None:
    answered = machine("releasing")
    answered.on_reject(CONTROL_RELEASED, 0.5)
    assert (answered.state, answered.unanswered) == (IDLE, False)
    silent = machine("releasing")
    silent.poll(PROFILE.response_timeout)
    assert (silent.state, silent.unanswered) == (IDLE, True)


# management readiness of a controlled component (Rule 2): (history, input, at) ->
# (ready for commands, messages sent)
READINESS = [
    ("requesting", ("ConfirmControl", CONTROL_ACCEPTED), 0.5, False,
     [QUERY_TIMEOUT, RESUME, QUERY_STATUS]),
    ("controlled", ("ReportStatus", READY), 0.5, True, []),
    ("controlled", ("ReportStatus", 0), 0.5, False, []),      # INITIALIZE: not yet
    ("controlled", ("timer",), 1.0, False, [RESUME, QUERY_STATUS]),  # 2nd and last try
    ("controlled", ("ReportStatus", 5), 0.5, False, []),      # EMERGENCY: never ready
]


@pytest.mark.parametrize(("history", "event", "at", "ready", "messages"), READINESS)
def test_management_readiness(catalogue: Any, history: str, event: Input, at: float,
                              ready: bool, messages: list[tuple[str, dict[str, Any]]]) -> None:
    ctl = machine(history, managed=True)
    out = feed(ctl, event, at)
    assert (ctl.ready, wire(catalogue, out)) == (ready, messages)


def test_readiness_gives_up_after_max_attempts_and_commands_anyway() -> None:
    ctl = machine("controlled", managed=True)  # attempt 1 at t = 0
    assert [o.name for o in ctl.poll(1.0)] == ["Resume", "QueryStatus"]  # attempt 2
    # the last one unanswered: no third Resume (only the control renewal, due now too)
    assert [o.name for o in ctl.poll(2.0)] == ["RequestControl"]
    assert ctl.ready and "did not reach READY after 2 Resume attempts" in ctl.note


def _enum(root: ET.Element, message: str) -> dict[str, int]:
    for node in root.iter():
        if node.tag.endswith("message_def") and node.get("name") == message:
            return {e.get("enum_const", ""): int(e.get("enum_index", "-1"))
                    for e in node.iter() if e.tag.endswith("value_enum")}
    raise AssertionError(f"{message} not in the JSIDL")


def test_response_codes_are_the_jsidl_ones() -> None:
    path = SHARED / "jaus" / "jsidl" / "urn.jaus.jss.core-v1.1" / "MessageSet" / "CommandClass.xml"
    if not path.is_file():
        pytest.skip("reference JSIDL not available")
    root = ET.parse(path).getroot()
    assert _enum(root, "ConfirmControl") == {
        "CONTROL_ACCEPTED": CONTROL_ACCEPTED, "NOT_AVAILABLE": NOT_AVAILABLE,
        "INSUFFICIENT_AUTHORITY": INSUFFICIENT_AUTHORITY}
    assert _enum(root, "RejectControl") == {
        "CONTROL_RELEASED": CONTROL_RELEASED, "NOT_AVAILABLE": NOT_AVAILABLE}
