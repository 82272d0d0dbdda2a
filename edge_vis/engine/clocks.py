"""Vehicles' clocks: read with QueryTime, set with SetTime when far off. No I/O, no clock.

The engine has no clock of its own: ``now`` (plus the runtime's ``wall_offset``) is the
relay's UTC time. The relay asks the first component offering Time for ReportTime when the
vehicle's services are known (again after it is found) and every ``time.query_period``;
the offset is the reported time minus the relay's time at the middle of the round trip
(the flight time is taken as half of it), in the millisecond resolution of JAUS TimeRec.

With ``time.set_on_discovery`` the first reading after discovery decides: a clock off by
more than ``time.set_threshold`` gets SetTime. The Time service obeys SetTime only from
its controlling client (AS5710 Time, Controlled state), so the relay takes control of the
component for the errand (:meth:`~edge_vis.engine.access.Access.update`, no Resume),
sends SetTime once control is confirmed, reads the clock again and lets control go. A
component controlled by someone with a higher authority refuses; that is noted and the
clock is left alone.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Mapping
from typing import Any

from edge_vis.engine.access import Access
from edge_vis.engine.control import ControlState
from edge_vis.engine.discovery import CORE
from edge_vis.engine.state import Changed, EngineState
from edge_vis.engine.vehicle import Vehicle
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.contract import ClockView

log = logging.getLogger(__name__)

TIME = CORE + "Time"
#: QueryTime presence vector: time and date
TIME_AND_DATE = 0b11
#: unanswered QueryTime after discovery asked again (response timeout apart) before
#: falling back to ``time.query_period``; also RequestControl attempts for SetTime
TIME_ATTEMPTS = 3


class Clocks:
    """Reads each vehicle's clock and sets it when the profile asks."""

    def __init__(self, state: EngineState, access: Access, changed: Changed) -> None:
        self._state = state
        self._access = access
        self._changed = changed

    def poll(self, vehicle: Vehicle, now: float) -> None:
        """QueryTime when due; SetTime once the errand's control is confirmed."""
        state = self._state
        if not vehicle.online or not vehicle.services_known or state.shutting_down:
            return
        providers = vehicle.providers(TIME)
        if not providers:
            return
        address = providers[0]
        if vehicle.time_round != vehicle.times_lost:  # discovered, or found again
            vehicle.time_round = vehicle.times_lost
            vehicle.time_attempts = 0
            vehicle.next_time_query = now
        if vehicle.next_time_query is not None and now >= vehicle.next_time_query:
            self._ask(vehicle, address, now)
        if address in vehicle.errands:
            self._errand(vehicle, address, now)

    def _ask(self, vehicle: Vehicle, address: JausAddress, now: float) -> None:
        profile = self._state.profile
        vehicle.time_asked[address] = now
        vehicle.time_attempts += 1
        period = profile.time.query_period
        answered = vehicle.clock_epoch == vehicle.times_lost
        if not answered and vehicle.time_attempts < TIME_ATTEMPTS:
            vehicle.next_time_query = now + profile.discovery.response_timeout
        else:  # a vehicle that never answers is asked at the normal pace
            vehicle.next_time_query = now + period if period > 0 else None
        self._state.send(address, "QueryTime", {"presence_vector": TIME_AND_DATE})

    def _errand(self, vehicle: Vehicle, address: JausAddress, now: float) -> None:
        ctl = vehicle.controls.get(address)
        if ctl is None:
            return
        if ctl.state is ControlState.REFUSED:
            self._done(vehicle, address, now,
                       f"SetTime not sent: control of {address} refused "
                       f"(code {ctl.last_response})")
        elif ctl.state is ControlState.REQUESTING and ctl.request_attempts > TIME_ATTEMPTS:
            self._done(vehicle, address, now,
                       f"SetTime not sent: {address} did not answer RequestControl")
        elif ctl.controlled:
            wall = now + self._state.wall_offset
            self._state.send(address, "SetTime", time_fields(wall), "control")
            vehicle.set_time_sent += 1
            self._state.counters["set_time_sent"] += 1
            log.info("vehicle %s: SetTime to %s (clock was %.3f s off)", vehicle.vehicle_id,
                     address, vehicle.clock.offset if vehicle.clock else 0.0)
            vehicle.time_asked[address] = now
            self._state.send(address, "QueryTime", {"presence_vector": TIME_AND_DATE})
            self._done(vehicle, address, now, "")

    def _done(self, vehicle: Vehicle, address: JausAddress, now: float, note: str) -> None:
        vehicle.errands.discard(address)
        self._access.update(vehicle, now)
        if note:
            log.warning("vehicle %s: %s", vehicle.vehicle_id, note)
            if vehicle.clock is not None:
                vehicle.clock = dataclasses.replace(
                    vehicle.clock, set_time_sent=vehicle.set_time_sent, note=note)
                self._changed(vehicle, "clock", now)

    def on_time(self, vehicle: Vehicle, source: JausAddress, fields: Mapping[str, Any],
                now: float) -> None:
        """ReportTime from ``source``: the offset, and whether to set the clock."""
        reported = epoch_of(fields, now + self._state.wall_offset)
        asked = vehicle.time_asked.pop(source, None)
        if reported is None or asked is None:
            self._state.counters["time_reports_unused"] += 1
            return
        round_trip = max(now - asked, 0.0)
        offset = reported - ((asked + now) / 2.0 + self._state.wall_offset)
        first = vehicle.clock_epoch != vehicle.times_lost
        vehicle.clock_epoch = vehicle.times_lost
        profile = self._state.profile.time
        if first:
            vehicle.next_time_query = now + profile.query_period if profile.query_period \
                else None
        vehicle.clock = ClockView(source, offset, round_trip, vehicle.set_time_sent, "")
        self._changed(vehicle, "clock", now)
        if first and profile.set_on_discovery and abs(offset) > profile.set_threshold:
            vehicle.errands.add(source)
            self._access.update(vehicle, now)


# -- JAUS TimeRec <-> seconds since the epoch (UTC), without the datetime module ------------


def _days_from_civil(year: int, month: int, day: int) -> int:
    """Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's algorithm)."""
    year -= month <= 2
    era = (year if year >= 0 else year - 399) // 400
    yoe = year - era * 400
    doy = (153 * (month + (-3 if month > 2 else 9)) + 2) // 5 + day - 1
    doe = yoe * 365 + yoe // 4 - yoe // 100 + doy
    return era * 146097 + doe - 719468


def _civil_from_days(days: int) -> tuple[int, int, int]:
    """(year, month, day) of a count of days since 1970-01-01."""
    days += 719468
    era = (days if days >= 0 else days - 146096) // 146097
    doe = days - era * 146097
    yoe = (doe - doe // 1460 + doe // 36524 - doe // 146096) // 365
    doy = doe - (365 * yoe + yoe // 4 - yoe // 100)
    mp = (5 * doy + 2) // 153
    day = doy - (153 * mp + 2) // 5 + 1
    month = mp + (3 if mp < 10 else -9)
    return yoe + era * 400 + (month <= 2), month, day


def time_fields(epoch: float) -> dict[str, Any]:
    """SetTime/ReportTime fields (UTC TimeRec: time and date) for ``epoch`` seconds."""
    ms_total = round(epoch * 1000)
    days, ms_of_day = divmod(ms_total, 86_400_000)
    year, month, day = _civil_from_days(days)
    seconds, ms = divmod(ms_of_day, 1000)
    return {
        "time_stamp": {"milliseconds": ms, "seconds": seconds % 60,
                       "minutes": seconds // 60 % 60, "hour": seconds // 3600, "day": day},
        "date_stamp": {"day": day, "month": month, "year": min(max(year - 2000, 0), 127)},
    }


def epoch_of(fields: Mapping[str, Any], near: float) -> float | None:
    """Seconds since the epoch a ReportTime says, None without a time stamp. A report
    without the date takes the year and month of ``near`` (the relay's time)."""
    stamp = fields.get("time_stamp")
    if not isinstance(stamp, Mapping):
        return None
    date = fields.get("date_stamp")
    if isinstance(date, Mapping):
        year, month = 2000 + int(date.get("year", 0)), int(date.get("month", 1))
    else:
        year, month, _day = _civil_from_days(int(near // 86_400))
    try:
        day = int(stamp.get("day", 1))
        if not (1 <= month <= 12 and 1 <= day <= 31):
            return None
        days = _days_from_civil(year, month, day)
        return (days * 86_400 + int(stamp.get("hour", 0)) * 3600
                + int(stamp.get("minutes", 0)) * 60 + int(stamp.get("seconds", 0))
                + int(stamp.get("milliseconds", 0)) / 1000.0)
    except (TypeError, ValueError):
        return None
