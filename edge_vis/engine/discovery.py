"""Discovery helpers: reading discovery reports into a system tree. No I/O.

The engine finds subsystems with a periodic broadcast QueryIdentification(2), then asks
each one QueryConfiguration(2) and QueryServices for every node and component (AS5710
Discovery). The helpers here turn the decoded reports into plain tuples and tolerate what
real robots send:

* the JTS example lists node 1 twice in ReportServices (one entry per service): entries
  for the same component are merged;
* core services are often not listed (JTS registers only the services it was built with
  by name): every listed service implies the services it inherits from
  (:data:`SERVICE_PARENTS`, from the JSIDL ``inherits-from`` chains), so a
  LocalWaypointListDriver implies Management, AccessControl, Events and Transport;
* the JTS example answers QueryIdentification(4) with a type-2 (subsystem) report: any
  ReportIdentification identifies the subsystem of its sender.

Decoded nested records may be flattened or kept as sub-dicts depending on the message
definition; :func:`pick` finds a field either way.

Peers also read the wildcards differently: JAUS++ looks node and component 255 of a
QueryServices up literally and answers with an empty list. :class:`ServiceDiscovery`
therefore never takes an empty or partial answer as the truth while the configuration
names components: it asks again by explicit IDs, a bounded number of times.
"""

from __future__ import annotations

import logging
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

log = logging.getLogger(__name__)

CORE = "urn:jaus:jss:core:"
MOBILITY = "urn:jaus:jss:mobility:"
ENV = "urn:jaus:jss:environmentSensing:"
#: the service liveness, status and the emergency stop all address
MANAGEMENT = CORE + "Management"

#: service URI -> the URI it inherits from (JSIDL ``inherits-from``; core v1.1,
#: mobility v1.0, environment sensing v1.0, IOP's EnhancedAccessControl).
SERVICE_PARENTS: Mapping[str, str] = {
    CORE + "Events": CORE + "Transport",
    CORE + "AccessControl": CORE + "Events",
    CORE + "Management": CORE + "AccessControl",
    CORE + "Time": CORE + "AccessControl",
    CORE + "Liveness": CORE + "Events",
    CORE + "Discovery": CORE + "Events",
    CORE + "ListManager": CORE + "Management",
    MOBILITY + "GlobalPoseSensor": CORE + "AccessControl",
    MOBILITY + "LocalPoseSensor": CORE + "AccessControl",
    MOBILITY + "VelocityStateSensor": CORE + "Events",
    MOBILITY + "AccelerationStateSensor": CORE + "Events",
    MOBILITY + "PrimitiveDriver": CORE + "Management",
    MOBILITY + "VelocityStateDriver": CORE + "Management",
    MOBILITY + "GlobalVectorDriver": CORE + "Management",
    MOBILITY + "LocalVectorDriver": CORE + "Management",
    MOBILITY + "GlobalWaypointDriver": CORE + "Management",
    MOBILITY + "LocalWaypointDriver": CORE + "Management",
    MOBILITY + "ListManager": CORE + "Management",
    MOBILITY + "GlobalWaypointListDriver": MOBILITY + "ListManager",
    MOBILITY + "LocalWaypointListDriver": MOBILITY + "ListManager",
    MOBILITY + "GlobalPathSegmentDriver": MOBILITY + "ListManager",
    MOBILITY + "LocalPathSegmentDriver": MOBILITY + "ListManager",
    ENV + "VisualSensor": CORE + "AccessControl",
    ENV + "StillImage": ENV + "VisualSensor",
    ENV + "DigitalVideo": ENV + "VisualSensor",
    ENV + "AnalogVideo": ENV + "VisualSensor",
    ENV + "RangeSensor": CORE + "AccessControl",
    "urn:jaus:jss:manipulator:ManipulatorListDriver": CORE + "ListManager",
    "urn:jaus:jss:manipulator:ManipulatorJointPositionListDriver":
        "urn:jaus:jss:manipulator:ManipulatorListDriver",
    "urn:jaus:jss:manipulator:ListManager": CORE + "Management",
    "urn:jaus:jss:manipulator:ManipulatorJointPositionsListDriver":
        "urn:jaus:jss:manipulator:ListManager",
    # IOP (jsidl-iop): answers QueryControl/QueryAuthority like its parent
    "urn:jaus:jss:iop:EnhancedAccessControl": CORE + "AccessControl",
}

MANIPULATOR = "urn:jaus:jss:manipulator:"
#: service URI -> the v1.x services that carry its messages: a component offering one of
#: them at a 1.x version is taken to offer it (at that version). Manipulator
#: v2.0 renamed the v1.0 velocity and list drivers and moved specifications, motion
#: profiles and the tool offset into services of their own, which v1.0's drivers and
#: sensors answered.
SERVICE_EQUIVALENTS: Mapping[str, tuple[str, ...]] = {
    MANIPULATOR + "ManipulatorJointVelocityDriver": (
        MANIPULATOR + "ManipulatorJointVelocitiesDriver",),
    MANIPULATOR + "PanTiltJointVelocityDriver": (MANIPULATOR + "PanTiltJointVelocitiesDriver",),
    MANIPULATOR + "ManipulatorJointPositionListDriver": (
        MANIPULATOR + "ManipulatorJointPositionsListDriver",),
    MANIPULATOR + "ManipulatorListDriver": (
        MANIPULATOR + "ManipulatorJointPositionsListDriver",
        MANIPULATOR + "ManipulatorEndEffectorPoseListDriver"),
    MANIPULATOR + "ManipulatorSpecificationService": (
        MANIPULATOR + "PrimitiveManipulator", MANIPULATOR + "ManipulatorJointPositionSensor",
        MANIPULATOR + "ManipulatorJointPositionDriver"),
    MANIPULATOR + "ManipulatorJointMotionProfile": (
        MANIPULATOR + "ManipulatorJointPositionDriver",
        MANIPULATOR + "ManipulatorJointVelocitiesDriver"),
    MANIPULATOR + "ManipulatorToolOffsetService": (
        MANIPULATOR + "ManipulatorEndEffectorPoseSensor",
        MANIPULATOR + "ManipulatorEndEffectorPoseDriver"),
    MANIPULATOR + "PanTiltSpecificationService": (
        MANIPULATOR + "PrimitivePanTilt", MANIPULATOR + "PanTiltJointPositionSensor"),
    MANIPULATOR + "PanTiltMotionProfileService": (
        MANIPULATOR + "PanTiltJointPositionDriver", MANIPULATOR + "PanTiltJointVelocitiesDriver"),
}
_EQUIVALENT_OF: dict[str, list[str]] = {}
for _newer, _older in SERVICE_EQUIVALENTS.items():
    for _uri in _older:
        _EQUIVALENT_OF.setdefault(_uri, []).append(_newer)

#: ReportIdentification.type values
IDENTIFICATION_TYPES: Mapping[int, str] = {
    10001: "VEHICLE", 20001: "OCU", 30001: "OTHER_SUBSYSTEM", 40001: "NODE", 50001: "PAYLOAD",
    60001: "COMPONENT",
}

Service = tuple[str, str]


def with_inherited(services: Iterable[Service]) -> tuple[Service, ...]:
    """``services`` plus every service they inherit from (version of the child), and the
    services of another version they stand for (:data:`SERVICE_EQUIVALENTS`)."""
    result: dict[str, str] = {}
    for uri, version in services:
        result.setdefault(uri, version)
    for uri, version in list(result.items()):
        for newer in _EQUIVALENT_OF.get(uri, ()) if version.startswith("1.") else ():
            result.setdefault(newer, version)
    for uri, version in list(result.items()):
        parent = SERVICE_PARENTS.get(uri)
        seen = {uri}
        while parent is not None and parent not in seen:
            seen.add(parent)
            result.setdefault(parent, version if parent.split(":")[3] == uri.split(":")[3]
                              else "1.0")
            parent = SERVICE_PARENTS.get(parent)
    return tuple(sorted(result.items()))


def pick(value: Any, name: str, default: Any = None) -> Any:
    """Field ``name`` of a decoded record, looking into nested records if needed."""
    if isinstance(value, Mapping):
        if name in value:
            return value[name]
        for child in value.values():
            if isinstance(child, Mapping):
                found = pick(child, name, _MISSING)
                if found is not _MISSING:
                    return found
    return default


_MISSING = object()


def _list(value: Any, name: str) -> list[Any]:
    found = pick(value, name, [])
    return list(found) if isinstance(found, list | tuple) else []


def services_from_report(fields: Mapping[str, Any]) -> dict[tuple[int, int], list[Service]]:
    """ReportServices fields -> ``{(node, component): [(uri, "major.minor"), ...]}``.

    Repeated node or component entries are merged (JTS lists node 1 once per service).
    """
    result: dict[tuple[int, int], list[Service]] = {}
    for node in _list(fields, "node_list"):
        node_id = pick(node, "node_id")
        for comp in _list(node, "component_list"):
            comp_id = pick(comp, "component_id")
            if node_id is None or comp_id is None:
                continue
            entry = result.setdefault((int(node_id), int(comp_id)), [])
            for svc in _list(comp, "service_list"):
                uri = pick(svc, "uri")
                if not isinstance(uri, str):
                    continue
                major = pick(svc, "major_version_number", 1)
                minor = pick(svc, "minor_version_number", 0)
                item = (uri, f"{major}.{minor}")
                if item not in entry:
                    entry.append(item)
    return result


def components_from_configuration(fields: Mapping[str, Any]) -> list[tuple[int, int]]:
    """ReportConfiguration fields -> ``[(node, component), ...]``."""
    found: list[tuple[int, int]] = []
    for node in _list(fields, "node_list"):
        node_id = pick(node, "node_id")
        for comp in _list(node, "component_list"):
            comp_id = pick(comp, "component_id")
            if node_id is not None and comp_id is not None:
                key = (int(node_id), int(comp_id))
                if key not in found:
                    found.append(key)
    return found


# == asking: which discovery queries to send, and when ======================================

#: Node or component ID 255 in a QueryServices: "all" (JSIDL); JAUS++ reads it literally.
WILDCARD = 255
#: Rounds spaced by the response timeout; later ones by the discovery period.
FAST_ROUNDS = 3
#: QueryServices sent to one subsystem before giving up until it is found again: a robot
#: that never answers must not cost its link forever.
MAX_ASKS = 8

Component = tuple[int, int]
Query = tuple[str, dict[str, Any]]


class Timing(Protocol):
    """What :class:`ServiceDiscovery` needs of the profile's discovery section."""

    @property
    def response_timeout(self) -> float: ...

    @property
    def period(self) -> float: ...


def query_services_fields(nodes: Mapping[int, Sequence[int]]) -> dict[str, Any]:
    """QueryServices fields asking for ``{node: [component, ...]}`` (255 = all)."""
    return {
        "node_list": [
            {"node_rec": {"node_id": node},
             "component_list": [{"component_id": c} for c in comps]}
            for node, comps in nodes.items()
        ]
    }


def _by_node(components: Iterable[Component]) -> dict[int, list[int]]:
    nodes: dict[int, list[int]] = {}
    for node, comp in components:
        comps = nodes.setdefault(node, [])
        if comp not in comps:
            comps.append(comp)
    return nodes


def _ids(components: Iterable[Component]) -> str:
    return ", ".join(f"{n}.{c}" for n, c in components) or "none"


@dataclass
class ServiceDiscovery:
    """How far finding one subsystem's components and services got. No I/O; time is passed in.

    Asks QueryConfiguration(2) and QueryServices for all nodes and components (255) first,
    as the JSIDL allows. An answer is not taken at its word when it contradicts what else is
    known: an empty ReportServices, or one without a component ReportConfiguration lists,
    makes it ask those components by explicit ID at once and on every later round; an empty
    ReportConfiguration makes it ask the node (QueryConfiguration(3)); a nameless
    ReportIdentification makes it ask the component directly (type 2, then type 4). A
    component that a non-empty answer to an explicit query leaves out has nothing to
    report (a legacy component). Rounds stop when every listed component has answered, or
    after :data:`MAX_ASKS` QueryServices. ``counters`` (the engine's) counts queries sent,
    empty answers, fallbacks and give-ups.
    """

    #: the vehicle, for log messages
    label: str = ""
    #: components ReportConfiguration listed, in order
    configuration: list[Component] = field(default_factory=list)
    configuration_known: bool = False
    #: components a ReportServices listed (with or without services)
    answered: set[Component] = field(default_factory=set)
    #: left out of a non-empty answer to an explicit query: nothing to report
    settled: set[Component] = field(default_factory=set)
    #: the components of the last explicit QueryServices (empty after a wildcard one)
    asked: tuple[Component, ...] = ()
    #: a wildcard answer came back empty or incomplete: ask by ID from now on
    explicit: bool = False
    #: some ReportIdentification gave a name
    named: bool = False
    asks: int = 0
    config_asks: int = 0
    ident_asks: int = 0
    #: services came from a static profile: never ask
    stopped: bool = False
    #: when the next round is due (None: nothing scheduled)
    next_at: float | None = None

    @property
    def known(self) -> bool:
        """True once some component's services are known: the vehicle can be served."""
        return bool(self.answered)

    @property
    def pending(self) -> list[Component]:
        """Components ReportConfiguration listed whose services are still unknown.

        Without a configuration nothing contradicts an answer: any non-empty one is taken
        as complete (the JTS example never answers QueryConfiguration).
        """
        if not self.configuration_known:
            return []
        return [c for c in self.configuration
                if c not in self.answered and c not in self.settled]

    def start(self, now: float) -> float | None:
        """Schedule the first round at ``now`` unless one ran already; the next due time."""
        if not self.stopped and self.asks == 0 and self.next_at is None:
            self.next_at = now
        return self.next_at

    def stop(self) -> None:
        """The services are known from elsewhere (a static profile): ask nothing more."""
        self.stopped = True
        self.next_at = None

    def restart(self, now: float) -> float | None:
        """Ask again from the first round (the vehicle came back after a give-up)."""
        if self.stopped or self.known or self.next_at is not None:
            return self.next_at
        self.asks = self.config_asks = self.ident_asks = 0
        self.next_at = now
        return now

    # -- rounds --------------------------------------------------------------------------

    def next_round(self, target: Component, now: float, timing: Timing,
                   counters: Counter[str]) -> list[Query]:
        """The queries due at ``now`` for the subsystem whose discovery answered at ``target``."""
        self.next_at = None
        if self.stopped or (self.known and not self.pending):
            return []
        if self.asks >= MAX_ASKS:
            counters["discovery_gave_up"] += 1
            missing = self.pending or [target]
            if self.known:
                log.info("vehicle %s: no services reported for %s after %d queries; serving "
                         "what is known", self.label, _ids(missing), self.asks)
            else:
                log.warning("vehicle %s: no services reported after %d queries (asked %s); "
                            "asking again when it is found again", self.label, self.asks,
                            _ids(missing))
            return []
        queries: list[Query] = []
        if not self.configuration_known:
            self.config_asks += 1
            queries.append(self._configuration_query(counters, self.config_asks % 2 == 0))
        if not self.named:
            self.ident_asks += 1
            query_type = 2 if self.ident_asks % 2 == 1 else 4
            queries.append(self._query("QueryIdentification", {"query_type": query_type},
                                       counters, fallback=True,
                                       why="no name from the subsystem yet"))
        wildcard = not self.explicit and self.asks % 2 == 0
        queries.append(self._services_query(target, wildcard, counters,
                                            why="no answer to the last one"))
        self.next_at = now + (timing.response_timeout if self.asks <= FAST_ROUNDS
                              else timing.period)
        return queries

    # -- answers -------------------------------------------------------------------------

    def on_services(self, report: Mapping[Component, Sequence[Service]], target: Component,
                    now: float, timing: Timing, counters: Counter[str]) -> list[Query]:
        """A ReportServices (``services_from_report``) arrived; queries to send at once."""
        if not report:
            counters["discovery_empty_answers"] += 1
            log.debug("vehicle %s: ReportServices lists no component", self.label)
        else:
            if self.asked:  # left out of an answer to an explicit query: nothing to report
                self.settled.update(c for c in self.asked if c not in report)
            self.answered.update(report)
            log.debug("vehicle %s: ReportServices for %s", self.label, _ids(report))
        return self._follow_up(target, now, timing, counters, empty=not report)

    def on_configuration(self, components: Sequence[Component], target: Component,
                         now: float, timing: Timing, counters: Counter[str]) -> list[Query]:
        """A ReportConfiguration arrived; queries to send at once."""
        queries: list[Query] = []
        if not components:
            counters["discovery_empty_answers"] += 1
            log.debug("vehicle %s: ReportConfiguration lists no component", self.label)
            if not self.configuration_known and not self.stopped and self.config_asks % 2:
                # a subsystem-wide answer came back empty: ask the node itself
                self.config_asks += 1
                queries.append(self._configuration_query(counters, True))
            return queries
        self.configuration += [c for c in components if c not in self.configuration]
        self.configuration_known = True
        log.debug("vehicle %s: ReportConfiguration lists %s", self.label, _ids(components))
        return self._follow_up(target, now, timing, counters, empty=False)

    def on_identification(self, name: str, counters: Counter[str]) -> None:
        """A ReportIdentification of this subsystem arrived (any query type)."""
        if name:
            self.named = True
        else:
            counters["discovery_empty_answers"] += 1
            log.debug("vehicle %s: ReportIdentification without a name", self.label)

    # -- helpers -------------------------------------------------------------------------

    def _follow_up(self, target: Component, now: float, timing: Timing,
                   counters: Counter[str], *, empty: bool) -> list[Query]:
        """Ask by ID at once when a wildcard answer was empty or left components out."""
        if self.stopped:
            return []
        pending = self.pending
        if self.known and not pending:
            if self.next_at is not None:
                log.debug("vehicle %s: services of every listed component known", self.label)
            self.next_at = None
            return []
        wanted = pending or ([target] if empty and not self.configuration_known else [])
        if not wanted or not (empty or self.known or self.explicit):
            return []  # nothing contradicts the wildcard yet: the round timer asks again
        if all(c in self.asked for c in wanted) or self.asks >= MAX_ASKS:
            return []  # asked by ID already: the round timer asks again
        self.explicit = True
        why = ("the answer was empty" if empty
               else f"the answers left out {_ids(pending)}")
        query = self._services_query(target, False, counters, why=why)
        self.next_at = now + timing.response_timeout
        return [query]

    def _services_query(self, target: Component, wildcard: bool, counters: Counter[str],
                        *, why: str) -> Query:
        self.asks += 1
        if wildcard:
            self.asked = ()
            return self._query("QueryServices",
                               query_services_fields({WILDCARD: [WILDCARD]}), counters,
                               fallback=False, why="")
        pending = self.pending
        first = [target] if target in pending or not self.configuration_known else []
        ids = list(dict.fromkeys([*first, *pending])) or [target]
        self.asked = tuple(ids)
        return self._query("QueryServices", query_services_fields(_by_node(ids)), counters,
                           fallback=True, why=why, ids=ids)

    def _configuration_query(self, counters: Counter[str], node: bool) -> Query:
        if node:
            return self._query("QueryConfiguration", {"query_type": 3}, counters,
                               fallback=True, why="no configuration of the subsystem")
        return self._query("QueryConfiguration", {"query_type": 2}, counters,
                           fallback=False, why="")

    def _query(self, name: str, fields: dict[str, Any], counters: Counter[str], *,
               fallback: bool, why: str, ids: Sequence[Component] = ()) -> Query:
        counters["discovery_queries_sent"] += 1
        if fallback:
            counters["discovery_fallbacks"] += 1
            log.debug("vehicle %s: %s %s (%s)", self.label, name,
                      f"for {_ids(ids)}" if ids else fields, why)
        else:
            log.debug("vehicle %s: %s %s", self.label, name,
                      "for all nodes and components" if name == "QueryServices" else fields)
        return name, fields
