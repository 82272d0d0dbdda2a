"""Serving or standing by: this relay's part in sharing vehicles with its peers. No I/O.

Several relays on one DDS domain may reach the same vehicle. Each publishes a
``RelayStatus`` sample every ``[serving] heartbeat`` seconds (and at once when what it
serves changes): its links and, per vehicle it reaches, its score (profile preference +
link quality, :func:`~edge_vis.engine.serving.link_quality`), whether it serves it and
for which operator it holds it. From its peers' samples and its own, each relay runs
:func:`~edge_vis.engine.serving.choose_server` per vehicle and

* **starts serving** a vehicle it is chosen for once no other live relay claims it (and,
  for a vehicle nobody served, once its own claim has been out for ``settle`` seconds,
  or at once when it knows no other relay and has run for ``settle`` seconds):
  it sets up the events, takes JAUS control for the operator the previous server held it
  for, and publishes the vehicle's state and telemetry, naming itself in VehicleStatus;
* **stops serving** a vehicle it is no longer chosen for: cancels the events, releases
  control, drops queued commands, and withdraws its DDS instances of the vehicle
  (:class:`Withdraw`), so that operators' plain readers see one writer per vehicle.

A relay not heard for ``lease`` seconds (its process died, its host lost the network) is
gone; a relay that stops says so (``leaving``). Standing by costs the liveness probes
only; commands for a vehicle served elsewhere are counted (``commands_other_relay``) and
not sent (those that came after a dead server's last sign of life are reported in
ControlStatus when this relay takes over); an emergency stop is sent by every relay that
reaches the vehicle (:mod:`edge_vis.engine.estop`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from edge_vis.engine.access import Access
from edge_vis.engine.arbitration import Holder
from edge_vis.engine.reports import Reports
from edge_vis.engine.serving import Claim, choose_server, link_quality
from edge_vis.engine.state import Changed, EngineState
from edge_vis.engine.subscriptions import SubscriptionState
from edge_vis.engine.vehicle import Vehicle
from edge_vis.kit.actions import Publish, Withdraw

log = logging.getLogger(__name__)

#: liveness periods link quality is measured over
QUALITY_WINDOW = 5


@dataclass
class Entry:
    """What a peer said about one vehicle."""

    score: float
    serving: bool
    operator_id: str = ""
    authority: int = 0


@dataclass
class Peer:
    """Another relay on the domain, as its last RelayStatus said."""

    heard_at: float
    vehicles: dict[str, Entry] = field(default_factory=dict)
    jaus_id: str = ""


class Duty:
    """Decides, per vehicle, whether this relay serves it (see the module docstring)."""

    def __init__(self, state: EngineState, access: Access, reports: Reports,
                 setup: Callable[[Vehicle, float], None], changed: Changed) -> None:
        self._state = state
        self._access = access
        self._reports = reports
        self._setup = setup
        self._changed = changed
        self.peers: dict[str, Peer] = {}
        self.started_at: float | None = None
        self.next_due: float | None = None
        #: vehicle id -> when this relay first claimed it (it reaches it)
        self._claimed_since: dict[str, float] = {}
        #: what this relay said last (its own claims, as its peers see them)
        self._said: dict[str, Entry] = {}
        #: vehicle id -> the relay that served it last (for the take-over log line)
        self.served_by: dict[str, str] = {}
        self.leaving = False
        #: relay -> when it was last heard, for the relays found gone
        self._gone: dict[str, float] = {}

    @property
    def name(self) -> str:
        return self._state.profile.relay_name

    # -- inputs -----------------------------------------------------------------------------
    def start(self, now: float) -> None:
        """The engine's first input: the settle time starts now."""
        if self.started_at is None:
            self.started_at = now
            self.next_due = now

    def on_status(self, sample: Mapping[str, Any], now: float) -> None:
        """A RelayStatus sample of some relay (this one's own are ignored)."""
        relay = str(sample.get("relay", ""))
        if not relay or relay == self.name:
            return
        if sample.get("leaving"):
            if self.peers.pop(relay, None) is not None:
                log.info("relay %s is leaving", relay)
            self._decide(now)
            return
        peer = self.peers.get(relay)
        if peer is None:
            log.info("relay %s joined", relay)
            peer = self.peers[relay] = Peer(now)
        peer.heard_at = now
        peer.jaus_id = str(sample.get("jaus_id", ""))
        before = {v: e.serving for v, e in peer.vehicles.items()}
        peer.vehicles = {
            str(v.get("vehicle_id", "")): Entry(float(v.get("score", 0.0)),
                                                bool(v.get("serving", False)),
                                                str(v.get("operator_id", "")),
                                                int(v.get("authority", 0)))
            for v in sample.get("vehicles", ()) or ()}
        for vehicle_id, entry in peer.vehicles.items():
            if entry.serving and vehicle_id in self._state.by_id:  # bounded by our table
                self.served_by[vehicle_id] = relay
                self._mirror_holder(vehicle_id, entry, now)
        if before != {v: e.serving for v, e in peer.vehicles.items()}:
            self._decide(now)

    def on_timer(self, now: float) -> None:
        """Heartbeat: forget silent peers, decide, publish this relay's status."""
        if self.next_due is None or now < self.next_due:
            return
        serving = self._state.profile.serving
        # a tick much later than due means this relay itself stalled (a loaded host): its
        # peers' samples may still be waiting to be read, so nobody is declared gone now
        stalled = now - self.next_due > serving.heartbeat
        for relay, peer in list(self.peers.items()):
            if now - peer.heard_at > serving.lease and not stalled:
                log.warning("relay %s gone: not heard for %.1f s", relay, now - peer.heard_at)
                self._state.counters["relays_gone"] += 1
                self._gone[relay] = peer.heard_at
                del self.peers[relay]
        if stalled:
            self._state.counters["relay_stalls"] += 1
        self._decide(now, publish=False)
        self._publish(now)

    def shutdown(self, now: float) -> None:
        """This relay stops: tell the peers at once so they take over without waiting
        for the lease (the engine's shutdown releases control and cancels events)."""
        self.leaving = True
        for vehicle in self._state.vehicles.values():
            vehicle.serving = False
        self._publish(now)

    # -- decisions ----------------------------------------------------------------------------
    def score(self, vehicle: Vehicle) -> float:
        """This relay's score for ``vehicle``: 0 when it does not reach it."""
        if not vehicle.online or self.leaving or self._state.shutting_down:
            return 0.0
        quality = link_quality(vehicle.heard, vehicle.probes, QUALITY_WINDOW)
        if quality <= 0:
            return 0.0
        serving = self._state.profile.serving
        bonus = 1.0 if vehicle.vehicle_id in serving.prefer else 0.0
        return serving.preference + bonus + quality

    def _decide(self, now: float, publish: bool = True) -> None:
        state = self._state
        if self.started_at is None or self.leaving or state.shutting_down:
            return
        settle = state.profile.serving.settle
        changed = False
        for vehicle in state.vehicles.values():
            vid = vehicle.vehicle_id
            mine = self._said.get(vid)
            if mine is None or mine.score <= 0:
                self._claimed_since.pop(vid, None)
            # with peers, decide on what they have seen of this relay; alone, on the now
            my_score = (mine.score if mine else 0.0) if self.peers else self.score(vehicle)
            claims = [Claim(self.name, my_score, vehicle.serving)]
            others = []
            for relay, peer in self.peers.items():
                entry = peer.vehicles.get(vid)
                if entry is not None:
                    claims.append(Claim(relay, entry.score, entry.serving))
                    if entry.serving:
                        others.append(relay)
            chosen = choose_server(claims, state.profile.serving.hysteresis, vid)
            if vehicle.serving and chosen is not None and chosen != self.name:
                # (a vehicle nobody reaches stays with its server: it keeps saying
                # offline, and sets the vehicle up again when it comes back)
                self._stop(vehicle, chosen, now)
                changed = True
            elif not vehicle.serving and chosen == self.name and not others:
                # peers must have seen this relay's claim before it takes a vehicle
                # nobody serves; alone (after the start-up settle), nobody can object
                since = self._claimed_since.get(vid)
                settled = now - self.started_at >= settle and (
                    not self.peers or (since is not None and now - since >= settle))
                if settled or vid in self.served_by:
                    self._start(vehicle, now)
                    changed = True
        if changed and publish:
            self._publish(now)

    def _start(self, vehicle: Vehicle, now: float) -> None:
        state = self._state
        previous = self.served_by.get(vehicle.vehicle_id)
        vehicle.serving = True
        self.served_by[vehicle.vehicle_id] = self.name
        state.touch(vehicle)
        holder = vehicle.arbitration.holder
        if previous and previous != self.name:
            state.counters["takeovers"] += 1
            gone = "gone" if previous in self._gone else "handed over"
            log.warning("vehicle %s: taking over from relay %s (%s)%s", vehicle.vehicle_id,
                        previous, gone, f", control for {holder.operator_id}" if holder else "")
            if previous in self._gone:
                self._report_unsent(vehicle, previous, self._gone[previous])
        else:
            log.info("vehicle %s: serving", vehicle.vehicle_id)
        for sub in vehicle.subscriptions.values():  # cancelled when it stood by: again
            if sub.state in (SubscriptionState.CANCELLING, SubscriptionState.DONE):
                sub.on_lost()
        self._setup(vehicle, now)
        self._changed(vehicle, "serving", now)

    def _report_unsent(self, vehicle: Vehicle, previous: str, last_heard: float) -> None:
        """Commands that came after the dead relay's last sign of life may never have
        been sent (by it or anyone): not resent (it may have sent some, and a stale
        command must not move a vehicle), but said in ControlStatus, not lost silently."""
        unsent = sum(1 for t in vehicle.not_sent_at if t > last_heard)
        vehicle.not_sent_at.clear()
        if unsent:
            self._state.counters["commands_unsent_in_takeover"] += unsent
            vehicle.arbitration.last_rejection = (
                f"{unsent} command(s) arrived while relay {previous} was failing and may "
                f"not have been sent")

    def _stop(self, vehicle: Vehicle, chosen: str | None, now: float) -> None:
        state = self._state
        state.counters["handovers"] += 1
        log.warning("vehicle %s: handing over to %s", vehicle.vehicle_id,
                    f"relay {chosen}" if chosen else "nobody (not reached)")
        self._reports.cancel(vehicle, now)
        vehicle.serving = False
        self._access.update(vehicle, now)  # releases control
        for slot in vehicle.commands.values():
            state.counters["commands_other_relay"] += slot.clear()
        if chosen:
            self.served_by[vehicle.vehicle_id] = chosen
        state.touch(vehicle)
        state.actions.append(Withdraw(vehicle.vehicle_id))

    def _mirror_holder(self, vehicle_id: str, entry: Entry, now: float) -> None:
        """The serving relay says whom it holds the vehicle for: a relay standing by
        keeps the same, to take control for that operator if it takes over."""
        vehicle = self._state.by_id.get(vehicle_id)
        if vehicle is None or vehicle.serving:
            return
        holder = Holder(entry.operator_id, entry.authority) if entry.operator_id else None
        vehicle.arbitration.holder = holder

    # -- output -------------------------------------------------------------------------------
    def _publish(self, now: float) -> None:
        state = self._state
        serving = state.profile.serving
        self.next_due = now + serving.heartbeat
        said: dict[str, Entry] = {}
        vehicles = []
        for vehicle in state.vehicles.values():
            score = self.score(vehicle)
            if score <= 0 and not vehicle.serving:
                continue
            holder = vehicle.arbitration.holder if vehicle.serving else None
            entry = Entry(score, vehicle.serving, holder.operator_id if holder else "",
                          holder.authority if holder else 0)
            said[vehicle.vehicle_id] = entry
            if score > 0:
                self._claimed_since.setdefault(vehicle.vehicle_id, now)
            vehicles.append({
                "vehicle_id": vehicle.vehicle_id,
                "link": (vehicle.profile.link if vehicle.profile and vehicle.profile.link
                         else state.link_of(vehicle.address) if vehicle.address else ""),
                "quality": link_quality(vehicle.heard, vehicle.probes, QUALITY_WINDOW)
                if vehicle.online else 0.0,
                "score": score, "serving": vehicle.serving,
                "operator_id": entry.operator_id, "authority": entry.authority,
            })
        self._said = said
        state.actions.append(Publish("RelayStatus", {
            "relay": self.name, "jaus_id": str(state.profile.jaus_id),
            "links": [{"link": lp.name, "up": True} for lp in state.profile.links],
            "vehicles": vehicles, "leaving": self.leaving,
            "heartbeat_ms": int(serving.heartbeat * 1000),
            "timestamp_ms": int((now + state.wall_offset) * 1000),
        }))


__all__ = ["QUALITY_WINDOW", "Duty", "Entry", "Peer"]
