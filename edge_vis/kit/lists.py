"""List Manager plans: load a list into a vehicle's list driver, read back what it holds. No I/O.

Every JAUS list driver (mobility's waypoint list and path segment drivers, the
manipulator's joint-position and end-effector-pose list drivers) inherits the core List
Manager, so a plan reaches any of them the same way, and is read back the same way:

* loading (:class:`ListLoader`): DeleteElement (every element), then SetElement batches of
  elements linked previous/next (UIDs 1..n), each request sent only after the vehicle
  confirmed the previous one, then the driver's own ExecuteList. A RejectElementRequest
  fails the load, except for the first "delete everything" (an empty list may refuse it);
* reading back (:class:`ListReadBack`): ReportElementList (an every-change event) gives the
  order; a list that changed is read element by element with QueryElement, a few at a time
  per component; ReportElementCount re-reads a list whose count differs.

A translator declares its drivers (:class:`ListDriver`: the service, the message set of
its ExecuteList, the element messages) and calls these from its hooks; they return
ordinary actions (:class:`~edge_vis.kit.actions.Command`, follow-up queries,
:class:`~edge_vis.kit.actions.Publish`), so control, throttling and pacing stay the
engine's. :func:`list_bindings` binds the List Manager's replies and reports to the
translator whose drivers sent them, so two translators with lists share the core messages.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from edge_vis.errors import DecodeError
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.actions import Action, Command, Publish, follow_up_query
from edge_vis.kit.contract import Binding, ReportSpec, TranslatorContext, VehicleView

#: the List Manager's answers to SetElement / DeleteElement
LIST_REPLIES = ("ConfirmElementRequest", "RejectElementRequest")
#: the List Manager's reports of what it holds
LIST_REPORTS = ("ReportElementList", "ReportElement", "ReportElementCount")
#: UID that DeleteElement reads as "every element"
ALL_ELEMENTS = 0xFFFF
#: elements per SetElement: keeps each one inside a single JUDP packet
ELEMENTS_PER_SET = 50
#: element queries one component has outstanding at a time: a long list is read in
#: batches, each asked for when the previous answers arrive, so it never floods a radio
QUERIES_IN_FLIGHT = 8
#: the request IDs of every loader: two translators loading lists into one component (a
#: List Manager serving a waypoint list driver and a manipulator list driver) never wait
#: for the same ID
_REQUEST_IDS = itertools.count(1)


@dataclass(frozen=True, slots=True)
class ListDriver:
    """A list driver a translator loads plans into: ``service`` (the URI commands go to),
    ``service_set`` (the set of its ExecuteList and Query/ReportActiveElement, which
    mobility and manipulator each define), ``elements`` (the messages an element may
    carry) and ``kind`` (the commands' throttle slot)."""

    service: str
    service_set: str
    elements: tuple[str, ...] = ()
    kind: str = "list"

    def read_back(self, rate: float = 0.5) -> ReportSpec:
        """The every-change event keeping its ReportElementList flowing."""
        return ReportSpec("ReportElementList", "QueryElementList", self.service, rate=rate,
                          on_change=True)

    def progress(self, rate: float = 1.0) -> ReportSpec:
        """The every-change event of its active element (``ReportActiveElement``)."""
        return ReportSpec("ReportActiveElement", "QueryActiveElement", self.service,
                          rate=rate, on_change=True, service_set=self.service_set)


def list_bindings(drivers: Sequence[ListDriver]) -> dict[str, Binding]:
    """The List Manager's messages bound to these drivers: replies and reports of a
    component offering one of them, and ReportActiveElement of their message set."""
    services = tuple(dict.fromkeys(d.service for d in drivers))
    sets = {d.service_set for d in drivers}
    bindings = {name: Binding(services=services) for name in (*LIST_REPLIES, *LIST_REPORTS)}
    if len(sets) == 1:
        bindings["ReportActiveElement"] = Binding(service_set=sets.pop())
    return bindings


def providers(vehicle: VehicleView, service: str) -> list[JausAddress]:
    """The components of ``vehicle`` offering ``service``."""
    return [address for address, services in vehicle.components.items()
            if any(uri == service for uri, _ in services)]


def list_steps(element: str, element_fields: Sequence[Mapping[str, Any]], catalogue: Any,
               per_set: int = ELEMENTS_PER_SET) -> list[tuple[str, dict[str, Any]]]:
    """DeleteElement then the SetElement batches of a plan; each element is ``element``
    encoded with the relay's catalogue (the context's, so a profile's own JSIDL applies)."""
    steps: list[tuple[str, dict[str, Any]]] = [
        ("DeleteElement", {"delete_element_list": [{"element_uid": ALL_ELEMENTS}]})]
    count = len(element_fields)
    for start in range(0, count, per_set):
        batch = range(start, min(count, start + per_set))
        elements = [{
            "element_uid": i + 1,
            "previous_uid": i,  # 0 before the first
            "next_uid": i + 2 if i + 1 < batch.stop else 0,
            "element_data": {"format": 0, "data": catalogue.encode(element,
                                                                   element_fields[i])},
        } for i in batch]
        steps.append(("SetElement", {"element_list": elements}))
    return steps


@dataclass
class ListLoad:
    """One plan on its way into a driver: ``state`` is LOADING, then EXECUTING once
    ExecuteList is sent, or FAILED (``reason`` says which request was refused)."""

    vehicle_id: str
    operator_id: str
    driver: ListDriver
    steps: list[tuple[str, dict[str, Any]]]
    execute: Callable[[], Mapping[str, Any]]
    component: JausAddress | None = None
    request_id: int | None = None
    pending: str = ""
    state: str = "LOADING"
    reason: str = ""


class ListLoader:
    """Loads plans into list drivers, one load per key (see the module docstring)."""

    def __init__(self) -> None:
        self.loads: dict[str, ListLoad] = {}

    def load(self, key: str, vehicle_id: str, operator_id: str, driver: ListDriver,
             element: str, element_fields: Sequence[Mapping[str, Any]], catalogue: Any,
             execute: Callable[[], Mapping[str, Any]],
             component: JausAddress | None = None) -> Command:
        """Start loading (replacing any load under ``key``): the first command.
        ``execute`` gives ExecuteList's fields when the list is complete."""
        self.loads[key] = ListLoad(vehicle_id, operator_id, driver,
                                   list_steps(element, element_fields, catalogue), execute,
                                   component)
        return self._next(key)

    def on_reply(self, key: str, name: str, fields: Mapping[str, Any]) -> list[Action] | None:
        """Confirm/RejectElementRequest: the next step (a Command), or [] when the load
        failed; None when the reply is not the one the load waits for."""
        load = self.loads.get(key)
        if load is None or load.request_id is None \
                or fields.get("request_id") != load.request_id:
            return None
        load.request_id = None
        # an empty list may refuse "delete everything": nothing to delete is fine
        if name == "RejectElementRequest" and load.pending != "DeleteElement":
            load.state = "FAILED"
            load.reason = f"{load.pending} refused (code {fields.get('response_code')})"
            return []
        return [self._next(key)]

    def _next(self, key: str) -> Command:
        load = self.loads[key]
        if load.steps:
            name, fields = load.steps.pop(0)
            load.pending = name
            load.request_id = next(_REQUEST_IDS) % 256
            fields = {"request_id_rec": {"request_id": load.request_id}, **fields}
        else:
            name, fields = "ExecuteList", dict(load.execute())
            load.state = "EXECUTING"
        # ExecuteList is both a mobility and a manipulator message: the driver's set's
        return Command(load.vehicle_id, load.operator_id, load.driver.kind, name, fields,
                       load.driver.service, component=load.component,
                       service_set=load.driver.service_set if name == "ExecuteList" else None)


@dataclass
class HeldList:
    """What the relay knows of one component's list (and, for a driver reporting it, its
    current target)."""

    count: int = -1
    order: list[int] = field(default_factory=list)
    elements: dict[int, dict[str, Any]] = field(default_factory=dict)
    asking: set[int] = field(default_factory=set)
    stale: set[int] = field(default_factory=set)
    current: dict[str, Any] = field(default_factory=dict)

    def complete(self) -> bool:
        """Every listed element read, and the count agrees."""
        return all(u in self.elements for u in self.order) and self.count == len(self.order)

    def listed(self) -> list[dict[str, Any]]:
        """The elements read so far, in list order."""
        return [self.elements[u] for u in self.order if u in self.elements]


#: (decoded element message name, its fields, uid, previous uid, next uid) -> an element
ElementOf = Callable[[str, Mapping[str, Any], int, int, int], dict[str, Any]]
#: (vehicle id, component, held list, context) -> the sample showing it
Show = Callable[[str, JausAddress, HeldList, TranslatorContext], Publish]


class ListReadBack:
    """The lists each component of a vehicle holds, read back from it (see the module
    docstring). ``element`` turns a decoded element into what the topic shows, ``show``
    makes the sample; ``drivers`` are the services whose lists an operator's query reads."""

    def __init__(self, drivers: Sequence[ListDriver], element: ElementOf, show: Show,
                 in_flight: int = QUERIES_IN_FLIGHT) -> None:
        self.drivers = tuple(drivers)
        self.element = element
        self.show = show
        self.in_flight = in_flight
        self.lists: dict[tuple[str, JausAddress], HeldList] = {}

    def on_report(self, name: str, fields: Mapping[str, Any],
                  ctx: TranslatorContext) -> list[Action]:
        """ReportElementList / ReportElement / ReportElementCount from ``ctx.source``."""
        held = self._held(ctx)
        if held is None or ctx.source is None:
            return []
        actions: list[Action] = []
        if name == "ReportElementList":
            order = [int(e.get("element_uid", 0)) for e in fields.get("element_list") or ()]
            held.order, held.count = order, len(order)
            held.elements = {u: e for u, e in held.elements.items()
                             if u in order and u not in held.stale}
            held.stale.clear()
            held.asking.clear()
        elif name == "ReportElement":
            uid = int(fields.get("element_uid", 0))
            held.asking.discard(uid)
            if uid not in held.order:
                return []  # an answer for an element removed meanwhile
            held.elements[uid] = self._decode(fields, ctx.catalogue)
        elif name == "ReportElementCount":
            held.count = int(fields.get("element_count", 0))
            if held.count != len(held.order):
                actions.append(follow_up_query(ctx.source, "QueryElementList"))
        return [*actions, *self._ask(ctx.source, held), self._show(ctx, held)]

    def on_current(self, current: dict[str, Any], ctx: TranslatorContext) -> list[Action]:
        """The driver at ``ctx.source`` reported its current target (shown as ``current``)."""
        held = self._held(ctx)
        if held is None or ctx.source is None:
            return []
        held.current = current
        return [*self._ask(ctx.source, held), self._show(ctx, held)]

    def refresh(self, vehicle_id: str, component: JausAddress) -> list[Action]:
        """Read ``component``'s whole list again (its elements may have been replaced)."""
        held = self.lists.setdefault((vehicle_id, component), HeldList())
        held.stale = set(held.elements)
        return [follow_up_query(component, "QueryElementList")]

    def on_query(self, sample: Mapping[str, Any], ctx: TranslatorContext) -> list[Action]:
        """An operator asks for the lists again: QueryElementCount and QueryElementList to
        every driver, through the engine (the operator holding the vehicle; throttled),
        every element read again."""
        vehicle = ctx.vehicle
        if vehicle is None:
            return []
        actions: list[Action] = []
        operator = str(sample.get("operator_id", ""))
        for driver in self.drivers:
            for address in providers(vehicle, driver.service):
                held = self.lists.setdefault((vehicle.vehicle_id, address), HeldList())
                held.stale = set(held.elements)
                for query in ("QueryElementCount", "QueryElementList"):
                    actions.append(Command(vehicle.vehicle_id, operator,
                                           f"plan_{query}_{address}", query, {},
                                           driver.service, component=address))
        return actions

    def _held(self, ctx: TranslatorContext) -> HeldList | None:
        if ctx.vehicle is None or ctx.source is None:
            return None
        return self.lists.setdefault((ctx.vehicle.vehicle_id, ctx.source), HeldList())

    def _decode(self, fields: Mapping[str, Any], catalogue: Any) -> dict[str, Any]:
        uid = int(fields.get("element_uid", 0))
        data = fields.get("element_data") or {}
        message, inner = "", dict[str, Any]()
        if data.get("format") == 0 and catalogue is not None:
            try:
                decoded = catalogue.decode(bytes(data.get("data") or b""))
            except DecodeError:  # the element is shown without its content
                decoded = None
            if decoded is not None and decoded.name is not None:
                message, inner = decoded.name, decoded.fields or {}
        return self.element(message, inner, uid, int(fields.get("previous_uid", 0)),
                            int(fields.get("next_uid", 0)))

    def _ask(self, component: JausAddress, held: HeldList) -> list[Action]:
        missing = [u for u in held.order if u not in held.elements and u not in held.asking]
        room = self.in_flight - len(held.asking)
        out: list[Action] = []
        for uid in missing[:max(0, room)]:
            held.asking.add(uid)
            out.append(follow_up_query(component, "QueryElement", {"element_uid": uid}))
        return out

    def _show(self, ctx: TranslatorContext, held: HeldList) -> Publish:
        assert ctx.vehicle is not None and ctx.source is not None
        return self.show(ctx.vehicle.vehicle_id, ctx.source, held, ctx)
