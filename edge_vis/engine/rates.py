"""Report rates of running vehicles: the bandwidth plan and profile reloads. No I/O.

A report's rate starts as the profile says; with a :class:`FleetPlanner` it is whatever
share of its link the plan gives it, recomputed when vehicles come and go, a provider
starts polling, or a link's measured rate changes. A reloaded profile retunes running
vehicles the same way. Either way a changed rate reaches the provider through the
subscription machine (UpdateEvent, a fresh CreateEvent, or a re-timed poll).
"""

from __future__ import annotations

import logging

from edge_vis.bandwidth.demands import VehicleWants
from edge_vis.config import RelayProfile
from edge_vis.engine.liveness import LIVENESS, MANAGEMENT
from edge_vis.engine.manager import TranslationManager
from edge_vis.engine.state import EngineState
from edge_vis.engine.subscriptions import Subscription, SubscriptionState
from edge_vis.engine.vehicle import Vehicle

log = logging.getLogger(__name__)

#: the highest rate CreateEvent can carry (u16 scaled to 0..1092 Hz)
MAX_RATE = 1092.0


class Rates:
    """Plans report rates and applies them (and reloaded profiles) to subscriptions."""

    def __init__(self, state: EngineState, manager: TranslationManager) -> None:
        self._state = state
        self._manager = manager

    def replan(self, now: float) -> None:
        """Plan report rates again and update the events whose rate changed."""
        state = self._state
        planner = state.planner
        if planner is None:
            return
        state.plan_dirty = False
        specs = {spec.report: spec for _tr, spec in self._manager.wanted_reports()}
        wants = []
        links: dict[str, str] = {}
        for vehicle in state.vehicles.values():
            if not vehicle.online or not vehicle.subscriptions:
                continue
            vp = vehicle.profile
            link = planner.link_for(vp.link if vp else "", vehicle.address)
            if not link:
                continue
            links[vehicle.vehicle_id] = link
            reports = tuple(
                (specs[sub.report], sub.polls)
                for sub in vehicle.subscriptions.values()
                if sub.report in specs and sub.state is not SubscriptionState.CANCELLING
            )
            live = sum(1 for address in vehicle.components
                       if vehicle.offers(address, LIVENESS)
                       or vehicle.offers(address, MANAGEMENT))
            wants.append(VehicleWants(vehicle.vehicle_id, link, vp, reports, max(live, 1)))
        # vehicles the profile puts on a planned link but not heard yet get a share now
        # (the reports their link-mates deliver), so the first one to answer is not given
        # the whole link and then slowed down behind its own backlog
        for vp in state.profile.vehicles:
            known = state.vehicles.get(vp.subsystem) if vp.subsystem is not None else None
            if not vp.link or (known is not None and (
                    known.times_lost or (known.online and known.subscriptions))):
                continue
            link = planner.link_for(vp.link, None)
            mates = [w for w in wants if w.link == link]
            expected = {spec.report: spec for w in mates for spec, _polled in w.reports}
            if link and expected:
                wants.append(VehicleWants(vp.vehicle_id, link, vp,
                                          tuple((spec, False) for spec in expected.values()),
                                          max(w.liveness_components for w in mates)))
        planner.plan(wants)
        for vehicle in state.vehicles.values():
            planned = links.get(vehicle.vehicle_id)
            if planned is None:
                continue
            for sub in vehicle.subscriptions.values():
                rate = planner.rate(planned, vehicle.vehicle_id, sub.report)
                if rate is None:
                    continue
                self._apply_rate(vehicle, sub, rate, now)

    def set_link_rate(self, link: str, bit_rate: float, now: float) -> None:
        """The measured rate of ``link`` changed: plan again."""
        planner = self._state.planner
        if planner is not None and planner.set_link_rate(link, bit_rate):
            self.replan(now)

    def apply_profile(self, profile: RelayProfile, now: float) -> list[str]:
        """Retune running vehicles to a reloaded ``profile``; return what was not applied.

        See :meth:`edge_vis.engine.engine.Engine.apply_profile`.
        """
        state = self._state
        state.profile = profile
        not_applied: list[str] = []
        defaults = {spec.report: spec.rate for _tr, spec in self._manager.wanted_reports()}
        for vehicle in state.vehicles.values():
            vp = profile.vehicle_by_subsystem(vehicle.subsystem)
            if vp is None and vehicle.announced_by is not None:
                # found by a family's discovery profile: follow that profile's new version
                was = vehicle.announced_by.discovery
                vp = next((p for p in profile.vehicles if p.is_family and p.discovery
                           is not None and was is not None
                           and (p.discovery.hello, p.discovery.messages)
                           == (was.hello, was.messages)), None)
                vehicle.announced_by = vp
            elif vehicle.announced_by is not None:
                vehicle.announced_by = vp if vp is not None and vp.discovery else None
            if vp is not None and vp.vehicle_id and vp.vehicle_id != vehicle.vehicle_id:
                not_applied.append(f"vehicle {vehicle.vehicle_id}: the profile now calls "
                                   f"subsystem {vehicle.subsystem} {vp.vehicle_id!r}")
            else:
                vehicle.profile = vp
            for sub in vehicle.subscriptions.values():
                sub.profile = profile.events
                if state.planner is not None:
                    continue  # the planner decides the rates (below)
                rate = min(profile.report_rate(sub.report, defaults.get(sub.report, sub.rate),
                                               vehicle.profile), MAX_RATE)
                if rate != sub.rate:
                    log.info("vehicle %s: %s at %g Hz (was %g)", vehicle.vehicle_id,
                             sub.report, rate, sub.rate)
                    state.send_requests(sub.provider, sub.set_rate(rate, now))
            for slot in vehicle.commands.values():
                slot.profile = profile.commands
            for ctl in vehicle.controls.values():
                ctl.profile = profile.control
                ctl.authority = profile.authority
        if state.planner is not None:
            state.planner.relay = profile
            self.replan(now)
        return not_applied

    def _apply_rate(self, vehicle: Vehicle, sub: Subscription, rate: float, now: float) -> None:
        state = self._state
        key = (vehicle.vehicle_id, sub.report)
        if rate <= 0:
            if key not in state.dropped:
                state.dropped.add(key)
                log.warning("vehicle %s: %s dropped: the link cannot carry even its minimum",
                            vehicle.vehicle_id, sub.report)
                if sub.state is not SubscriptionState.NEW:
                    state.send_requests(sub.provider, sub.cancel(now))
                sub.reason = "dropped by the bandwidth plan"
            return
        if key in state.dropped:
            state.dropped.discard(key)
            sub.rate = rate
            state.send_requests(sub.provider, sub.resume(now))
            state.touch(vehicle)
            return
        if abs(rate - sub.rate) > 1e-9:
            log.info("vehicle %s: %s planned at %.2f Hz (was %.2f)", vehicle.vehicle_id,
                     sub.report, rate, sub.rate)
            state.send_requests(sub.provider, sub.update_rate(rate, now))
            state.touch(vehicle)
