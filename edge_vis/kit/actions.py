"""Actions the engine and translators emit: frozen values, compared with ``==``. No I/O.

The engine never performs anything itself: it returns these from
:meth:`~edge_vis.engine.engine.Engine.drain_actions` and the runtime carries them out.

* :class:`SendMessage` - encode ``fields`` as message ``name`` (of ``service_set`` when
  two sets use the name) through the catalogue and send it to ``destination`` (the router
  picks the link).
* :class:`Publish` - write ``sample`` (a dict) to DDS ``topic``.
* :class:`ShutdownComplete` - every goodbye message has been emitted (and answered, or
  waited for long enough); the runtime may close links.

Translators return :class:`Publish`, :class:`Command`, :class:`DeclareVehicle`,
:class:`EmergencyRequest` and :class:`Dropped`; the engine turns a ``Command`` into a
``SendMessage`` only when the operator holds control, the vehicle's component is controlled
and ready, and the rate and lifespan allow it. A translator returns a ``SendMessage``
itself only for a follow-up query a report calls for (the elements of a list that changed,
the plan of a new mission), made by :func:`follow_up_query`: a query needs no control, and
the link paces and queues it like the engine's own queries.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Union

from edge_vis.jaus.address import JausAddress

#: JAUS transport priority values (AS5669A): low, standard, high, safety critical.
PRIORITY_LOW, PRIORITY_STANDARD, PRIORITY_HIGH, PRIORITY_SAFETY = 0, 1, 2, 3
#: the traffic class that jumps every link queue (see :mod:`edge_vis.routing.router`)
EMERGENCY_CLASS = "emergency"


@dataclass(frozen=True, slots=True)
class SendMessage:
    """Send JAUS message ``name`` with decoded ``fields`` to ``destination``.

    ``service_set`` picks the definition when several message sets use ``name``
    (``ExecuteList`` is both a mobility and a manipulator message); None means the first
    one the catalogue holds.
    """

    destination: JausAddress
    name: str
    fields: Mapping[str, Any] = field(default_factory=dict)
    priority: int = PRIORITY_STANDARD
    service_set: str | None = None
    #: scheduling class on the link (control, command, liveness, telemetry, bulk; "" =
    #: by ``priority`` only); the link profile maps it to a JAUS priority. The
    #: ``emergency`` class is sent ahead of everything, never paced, queued or dropped
    traffic_class: str = ""


@dataclass(frozen=True, slots=True)
class Publish:
    """Write one sample to a DDS topic; the bridge turns the dict into the topic's type.

    ``merge`` names the members that identify the instance (``("vehicle_id",)``): the
    engine then publishes the sample merged over the latest one of that instance, whoever
    published it, so several reports (of several translators) can fill one state topic
    without clearing each other's members; a member that is absent or NaN keeps its
    earlier value."""

    topic: str
    sample: Mapping[str, Any]
    merge: tuple[str, ...] = ()


@dataclass(frozen=True, slots=True)
class Command:
    """A JAUS command a translator wants sent to a vehicle on behalf of an operator.

    ``service`` is the URI of the service that executes it; the engine sends it to the
    vehicle's component offering that service. ``kind`` groups commands for throttling
    (latest wins per vehicle and kind). ``stop`` are the fields of the same message that
    stop the vehicle: when given, the command is a *motion* command: it is refused in
    EMERGENCY/FAILURE and, when the operator's commands of this kind stop for longer
    than the dead-man timeout, the engine sends ``stop`` itself. ``service_set`` names the
    message set of ``name`` when two sets use that name (see :class:`SendMessage`).
    ``rate`` (Hz) and ``lifespan`` (s), when given, replace the profile's ``[commands]``
    throttle for this kind (a profile's command mapping sets them per command).

    ``needs_ready``: False for commands that need control but not a READY component
    (Management's Standby, Resume, Shutdown, Reset). ``component`` sends it to that one
    component (it must offer ``service``); else ``every_provider`` sends it to every
    component offering ``service``, and by default it goes to the first one.
    """

    vehicle_id: str
    operator_id: str
    kind: str
    name: str
    fields: Mapping[str, Any]
    service: str
    stop: Mapping[str, Any] | None = None
    priority: int = PRIORITY_STANDARD
    service_set: str | None = None
    needs_ready: bool = True
    component: JausAddress | None = None
    every_provider: bool = False
    rate: float | None = None
    lifespan: float | None = None


@dataclass(frozen=True, slots=True)
class DeclareVehicle:
    """Declare a vehicle that does not do standard discovery (e.g. after a custom hello).

    ``components`` maps each component address to its ``(uri, version)`` services.
    """

    vehicle_id: str
    components: Mapping[JausAddress, tuple[tuple[str, str], ...]]
    name: str = ""
    vehicle_type: str = ""


@dataclass(frozen=True, slots=True)
class EmergencyRequest:
    """An operator asks the relay to set (``action="set"``) or clear (``"clear"``) the
    emergency stop of a vehicle.

    Not a :class:`Command`: the engine sends it without control, ahead of every other
    message on the link, never throttled or expired, retransmitted until the vehicle
    confirms; who may set and clear is the profile's ``[emergency]`` rule.
    """

    vehicle_id: str
    operator_id: str
    action: str
    authority: int = 0
    reason: str = ""


@dataclass(frozen=True, slots=True)
class Dropped:
    """Part of a message a translator could not use, and why (``reason``: short and fixed,
    it names a counter: ``"range compression bzip2: undecodable"``). The relay counts it per
    translator and reason and logs it; the rest of the message is translated."""

    reason: str
    detail: str = ""


@dataclass(frozen=True, slots=True)
class ShutdownComplete:
    """The engine has said goodbye to every vehicle; links may close."""

    unanswered: int = 0


@dataclass(frozen=True, slots=True)
class Withdraw:
    """Stop writing every DDS instance of ``vehicle_id``: another relay serves it now
    (emitted by the engine, :mod:`edge_vis.engine.duty`; translators do not return it)."""

    vehicle_id: str


def follow_up_query(destination: JausAddress, name: str,
                    fields: Mapping[str, Any] | None = None) -> SendMessage:
    """A query a report calls for (see the module docstring), to ``destination``: no
    control needed, queued and paced on the link as telemetry like the engine's queries."""
    return SendMessage(destination, name, dict(fields or {}), traffic_class="telemetry")


Action = Union[SendMessage, Publish, Command, DeclareVehicle, EmergencyRequest,  # noqa: UP007
               Dropped, ShutdownComplete, Withdraw]
