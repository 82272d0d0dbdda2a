"""Which relay serves a vehicle: the decision table, and two engines sharing a vehicle.

The engines exchange their RelayStatus samples by hand here (the DDS side is the e2e
tests'); both hear the same scripted robot, as two relays in reach of one vehicle do.
"""

from __future__ import annotations

from typing import Any

import pytest

from edge_vis.engine.serving import Claim, choose_server, link_quality
from edge_vis.kit.actions import Publish, Withdraw

from .conftest import Harness, profile, published, sent
from .test_engine import REPORTS, ROBOT, VID, WRENCH, discover, take_control

C = Claim

# (claims, hysteresis, chosen, why)
TABLE: list[tuple[list[Claim], float, str | None, str]] = [
    ([], 0.25, None, "nobody reaches it"),
    ([C("a", 0.0), C("b", 0.0)], 0.25, None, "a score of 0 is no candidate"),
    ([C("a", 1.0)], 0.25, "a", "the only candidate"),
    ([C("a", 0.6), C("b", 1.0)], 0.25, "b", "nobody serves: the best score"),
    ([C("a", 0.8, True), C("b", 1.0)], 0.25, "a", "incumbent within hysteresis keeps it"),
    ([C("a", 0.6, True), C("b", 1.0)], 0.25, "b", "better by more than hysteresis"),
    ([C("a", 0.75, True), C("b", 1.0)], 0.25, "a", "exactly hysteresis: no move"),
    ([C("a", 1.0, True), C("b", 2.0)], 0.25, "b", "a profile preference (+1) moves it"),
    ([C("a", 0.0, True), C("b", 0.2)], 0.25, "b", "the incumbent lost it: any reacher"),
    ([C("a", 0.6, True), C("b", 1.0, True)], 0.25, "b", "two incumbents: better score"),
    ([C("a", 0.9, True), C("b", 1.0, True), C("c", 1.2)], 0.25, "b",
     "two incumbents, challenger within hysteresis of the better one"),
    ([C("a", 0.6), C("b", 1.0)], 0.0, "b", "no hysteresis"),
]


@pytest.mark.parametrize("claims,hysteresis,chosen,why", TABLE,
                         ids=[row[3] for row in TABLE])
def test_choose_server(claims: list[Claim], hysteresis: float, chosen: str | None,
                       why: str) -> None:
    assert choose_server(claims, hysteresis) == chosen, why
    assert choose_server(reversed(claims), hysteresis) == chosen, "order must not matter"


def test_equal_scores_agree_everywhere_and_spread_the_fleet() -> None:
    """Two relays started at the same instant with equal links: every relay names the
    same one for a vehicle (whatever order it lists the claims in), and a fleet in reach
    of three relays spreads over all three rather than piling on the lowest name."""
    wins = {"r1": 0, "r2": 0, "r3": 0}
    for n in range(300):
        vehicle = f"ugv-{n}"
        claims = [C("r1", 1.0), C("r2", 1.0), C("r3", 1.0)]
        chosen = choose_server(claims, 0.25, vehicle)
        assert chosen is not None
        assert choose_server(reversed(claims), 0.25, vehicle) == chosen
        both = [C("r1", 1.0, True), C("r2", 1.0, True), C("r3", 1.0, True)]
        assert choose_server(both, 0.25, vehicle) == chosen, "split brain: the same one stays"
        wins[chosen] += 1
    assert all(60 < count < 140 for count in wins.values()), wins


@pytest.mark.parametrize("heard,probes,quality", [
    (0b0, 0, 1.0), (0b1, 1, 1.0), (0b0, 1, 0.0), (0b11111, 9, 1.0), (0b10101, 5, 0.6),
    (0b1111100000, 10, 0.0), (0b11, 2, 1.0), (0b01, 2, 0.5),
])
def test_link_quality(heard: int, probes: int, quality: float) -> None:
    assert link_quality(heard, probes, 5) == pytest.approx(quality)


# -- two engines -----------------------------------------------------------------------------

def relay(catalogue: Any, jaus_id: str, **serving: Any) -> Harness:
    prof = profile(relay={"jaus_id": jaus_id, "authority": 100},
                   serving={"heartbeat": 0.25, "lease": 1.0, "settle": 0.5, **serving})
    from edge_vis.engine.engine import Engine
    from translators.core import CoreTranslator
    from translators.emergency import EmergencyTranslator
    from translators.mobility import MobilityTranslator

    h = Harness(catalogue, prof)
    h.engine = Engine(prof, [CoreTranslator(), MobilityTranslator(), EmergencyTranslator()],
                      catalogue=catalogue, arbitrate=True)
    return h


def statuses(actions: list[Any]) -> list[dict[str, Any]]:
    return [dict(a.sample) for a in actions
            if isinstance(a, Publish) and a.topic == "RelayStatus"]


class Pair:
    """Two relays hearing one robot, their RelayStatus carried between them."""

    def __init__(self, catalogue: Any, a: dict[str, Any] | None = None,
                 b: dict[str, Any] | None = None) -> None:
        self.a = relay(catalogue, "42.1.1", **(a or {}))
        self.b = relay(catalogue, "43.1.1", **(b or {}))
        self.relays = {"a": self.a, "b": self.b}
        self.alive = {"a": True, "b": True}
        self.hears = {"a": True, "b": True}

    def run(self, seconds: float, step: float = 0.05, events: bool = True) -> list[Any]:
        """Advance both clocks; the robot answers what each relay asks (liveness and
        events), RelayStatus crosses over at once."""
        out: list[Any] = []
        for _ in range(round(seconds / step)):
            for name, h in self.relays.items():
                if not self.alive[name]:
                    continue
                acts = h.advance(step)
                if self.hears[name]:
                    if sent(acts, "QueryHeartbeatPulse"):
                        acts += h.deliver(ROBOT, "ReportHeartbeatPulse")
                    for create in sent(acts, "CreateEvent"):
                        acts += h.deliver(ROBOT, "ConfirmEventRequest", {
                            "request_id": create.fields["request_id"], "event_id": 0,
                            "confirmed_periodic_rate": create.fields["requested_periodic_rate"]})
                    for _req in sent(acts, "RequestControl"):
                        acts += h.deliver(ROBOT, "ConfirmControl", {"response_code": 0})
                    if sent(acts, "QueryStatus") or sent(acts, "Resume"):
                        acts += h.deliver(ROBOT, "ReportStatus", {"status": 1, "reserved": 0})
                    if events and h.engine.vehicle(VID) and h.engine.vehicle(VID).serving:
                        report = h.catalogue.encode("ReportGlobalPose", REPORTS["ReportGlobalPose"])
                        acts += h.deliver(ROBOT, "Event", {"event_id": 0, "sequence_number": 0,
                                                           "report_message": report})
                out += [(name, a) for a in acts]
                for sample in statuses(acts):
                    for other, peer in self.relays.items():
                        if other != name and self.alive[other]:
                            peer.engine.receive_relay_status(sample, peer.now)
                            out += [(other, a) for a in peer.drain()]
        return out

    def start(self) -> None:
        """Both discover the robot and agree; then ``a`` names the server, ``b`` the
        relay standing by (which one wins equal links is the rendezvous hash's)."""
        discover_both(self)
        self.run(2.0)
        (server,) = self.serving()
        if server == "b":
            self.a, self.b = self.b, self.a
            self.relays = {"a": self.a, "b": self.b}

    def serving(self) -> set[str]:
        return {n for n, h in self.relays.items()
                if self.alive[n] and (v := h.engine.vehicle(VID)) is not None and v.serving}


def discover_both(pair: Pair) -> None:
    for h in (pair.a, pair.b):
        discover(h, events=False)


def test_two_relays_started_together_agree_on_one(catalogue: Any) -> None:
    pair = Pair(catalogue)
    discover_both(pair)
    out = pair.run(3.0)
    (server,) = pair.serving()  # equal links: one serves, the other stands by
    standby = "b" if server == "a" else "a"
    b_sent = {a.name for n, a in out if n == standby and hasattr(a, "name")}
    assert b_sent <= {"QueryHeartbeatPulse", "QueryStatus", "QueryIdentification"}, \
        f"a relay standing by keeps to liveness, sent {b_sent}"
    assert not [a for n, a in out if n == standby and isinstance(a, Publish)
                and a.topic != "RelayStatus"], "a relay standing by publishes nothing"
    assert published([a for n, a in out if n == server], "GlobalPose")
    status = published([a for n, a in out if n == server], "VehicleStatus")[-1]
    assert status["relay"] == str(pair.relays[server].engine.profile.jaus_id)


def test_commands_go_through_the_serving_relay_only(catalogue: Any) -> None:
    pair = Pair(catalogue)
    pair.start()
    for h in (pair.a, pair.b):
        take_control(h)
    pair.run(0.5)
    assert pair.b.engine.vehicle(VID).arbitration.holder.operator_id == "op1"
    out_a = pair.a.sample("WrenchEffortCommand", WRENCH) + pair.a.advance(0.1)
    out_b = pair.b.sample("WrenchEffortCommand", WRENCH) + pair.b.advance(0.1)
    assert sent(out_a, "SetWrenchEffort")
    assert not sent(out_b, "SetWrenchEffort") and not sent(out_b, "RequestControl")
    assert pair.b.engine.counters["commands_other_relay"] >= 1


def test_serving_relay_gone_is_taken_over_with_its_operator(catalogue: Any) -> None:
    pair = Pair(catalogue)
    pair.start()
    take_control(pair.a)  # the operator's request reached only the serving relay
    out = pair.run(0.5)
    assert pair.b.engine.vehicle(VID).arbitration.holder.operator_id == "op1", \
        "the relay standing by knows for whom the vehicle is held, from RelayStatus"
    pair.alive["a"] = False  # killed: no goodbye
    pair.b.sample("WrenchEffortCommand", WRENCH)  # a's job still, as far as b knows
    pair.b.sample("WrenchEffortCommand", WRENCH)
    out = pair.run(2.0)
    assert pair.serving() == {"b"}
    b = [a for n, a in out if n == "b"]
    control = published(b, "ControlStatus")[0]
    assert control["last_rejection"].startswith("2 command(s) arrived while relay 4"), \
        "commands the dead relay may not have sent are reported, not resent"
    assert not [m for m in sent(b, "SetWrenchEffort")], "nor sent late"
    assert sent(b, "CreateEvent") and sent(b, "RequestControl"), \
        "the new server re-creates events and takes control for the operator"
    assert pair.b.engine.counters["takeovers"] == 1
    out_b = pair.b.sample("WrenchEffortCommand", WRENCH) + pair.b.advance(0.2)
    assert sent(out_b, "SetWrenchEffort"), "the operator drives on without asking again"


def test_relay_losing_the_vehicle_hands_it_over(catalogue: Any) -> None:
    pair = Pair(catalogue)
    pair.start()
    assert pair.serving() == {"a"}
    pair.hears["a"] = False  # a's radio path to the robot fades
    out = pair.run(4.0)
    assert pair.serving() == {"b"}
    a = [x for n, x in out if n == "a"]
    assert any(isinstance(x, Withdraw) for x in a), "a withdraws its DDS instances"


def test_quality_wobble_within_hysteresis_does_not_move_it(catalogue: Any) -> None:
    pair = Pair(catalogue)
    pair.start()
    before = pair.a.engine.counters["handovers"]
    for _ in range(6):  # one liveness answer in five lost, now and then
        pair.hears["a"] = False
        pair.run(0.3)
        pair.hears["a"] = True
        pair.run(1.2)
    assert pair.serving() == {"a"}
    assert pair.a.engine.counters["handovers"] == before


@pytest.mark.parametrize("preferred", ["a", "b"])
@pytest.mark.parametrize("key,value", [("prefer", [VID]), ("preference", 2.0)])
def test_profile_preference_picks_the_relay(catalogue: Any, preferred: str, key: str,
                                            value: Any) -> None:
    pair = Pair(catalogue, **{preferred: {key: value}})
    discover_both(pair)
    pair.run(3.0)
    assert pair.serving() == {preferred}


def test_profile_preference_moves_a_served_vehicle(catalogue: Any) -> None:
    """A relay whose profile now prefers the vehicle (a reload) takes it from the
    relay serving it, through a planned hand-over."""
    import dataclasses

    pair = Pair(catalogue)
    pair.start()
    engine = pair.b.engine
    engine.profile = dataclasses.replace(engine.profile, serving=dataclasses.replace(
        engine.profile.serving, prefer=(VID,)))
    pair.run(1.0)
    assert pair.serving() == {"b"}
    assert pair.a.engine.counters["handovers"] == 1


def test_leaving_relay_hands_over_at_once(catalogue: Any) -> None:
    pair = Pair(catalogue)
    pair.start()
    pair.a.engine.shutdown(pair.a.now)
    leaving = statuses(pair.a.drain())
    assert leaving and leaving[-1]["leaving"]
    pair.b.engine.receive_relay_status(leaving[-1], pair.b.now)
    pair.b.drain()
    pair.alive["a"] = False
    pair.run(0.1)
    assert pair.serving() == {"b"}, "no lease to wait for"


def test_emergency_stop_is_sent_by_a_relay_standing_by(catalogue: Any) -> None:
    """Safety first: SetEmergency is accepted from any client, so the stop goes out from
    every relay that reaches the vehicle, in case the one serving it is dead or cut off."""
    pair = Pair(catalogue)
    pair.start()
    assert not pair.b.engine.vehicle(VID).serving
    out = pair.b.sample("EmergencyCommand", {"vehicle_id": VID, "operator_id": "op1",
                                             "authority": 10, "action": "SET"})
    assert sent(out, "SetEmergency")


def test_a_vehicle_nobody_reaches_stays_with_its_server(catalogue: Any) -> None:
    """A lone relay that loses a vehicle keeps it (its VehicleStatus says offline, no
    instance is withdrawn) and sets it up again when it comes back."""
    pair = Pair(catalogue)
    pair.alive["b"] = False
    discover(pair.a, events=False)
    pair.run(2.0)
    assert pair.serving() == {"a"}
    pair.hears["a"] = False
    out = pair.run(4.0)
    assert not pair.a.engine.vehicle(VID).online
    assert pair.serving() == {"a"}
    assert not [x for _, x in out if isinstance(x, Withdraw)]
    assert published([x for _, x in out], "VehicleStatus")[-1]["online"] is False
    pair.hears["a"] = True
    found = pair.a.deliver(ROBOT, "ReportHeartbeatPulse")
    out = pair.run(1.0)
    assert sent(found + [x for _, x in out], "CreateEvent"), "events set up again when found"


def test_a_relay_that_stalled_declares_nobody_gone_at_once(catalogue: Any) -> None:
    """A loaded host stops b's loop for 2 s: the peers' samples wait unread, so the late
    tick must not read as every peer gone (and b take over what a serves)."""
    pair = Pair(catalogue)
    pair.start()
    b = pair.b
    b.now += 2.0  # no timer ran meanwhile
    b.engine.on_timer(b.now)
    b.drain()
    assert "42.1.1" in b.engine.duty.peers or "43.1.1" in b.engine.duty.peers
    assert b.engine.counters["relays_gone"] == 0 and b.engine.counters["relay_stalls"] == 1
    pair.a.now = b.now - 0.05  # a was fine all along: its next status comes in
    pair.run(1.0)
    assert pair.serving() == {"a"} and b.engine.counters["relays_gone"] == 0
