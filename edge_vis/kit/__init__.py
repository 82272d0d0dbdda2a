"""The translation kit: the public API a translator is written in. No I/O.

A translator plugin imports from here and from nothing else of edge-vis::

    from edge_vis.kit import CommandRule, From, Put, ReportRule, RuleTranslator

* the contract (:mod:`edge_vis.kit.contract`): :class:`Translator` with its hooks,
  :class:`TranslatorContext` (time, relay, vehicles, live catalogue), :class:`VehicleView`,
  :class:`ReportSpec`, :func:`derive_vehicle_id`, :class:`JausAddress`;
* the actions a hook returns (:mod:`edge_vis.kit.actions`): :class:`Publish`,
  :class:`Command`, :class:`DeclareVehicle`, :class:`EmergencyRequest`, :class:`Dropped`
  (the engine's
  own :class:`SendMessage` and :class:`ShutdownComplete` live beside them);
* the rule vocabulary (:mod:`edge_vis.kit.rules`): report and command tables that
  :class:`RuleTranslator` runs and ``edge-vis mappings`` prints, and :func:`path_problem`
  and :func:`resolve_path` to check a field path against a message definition;
* List Manager plans (:mod:`edge_vis.kit.lists`): :class:`ListDriver` declares a list
  driver, :class:`ListLoader` loads a plan into it, :class:`ListReadBack` reads back what it
  holds, :func:`list_bindings` binds the List Manager's messages to the translator's drivers;
* :func:`setting` and :func:`read_table`, from the validation kit (:mod:`edge_vis.schema`),
  to declare a translator's options as a dataclass (:attr:`Translator.options_type`).

Control, events, throttling and the dead-man stop are the engine's: a translator only maps.
"""

from __future__ import annotations

from edge_vis.errors import ConfigError, DecodeError, EncodeError
from edge_vis.jaus.address import JausAddress
from edge_vis.kit.actions import (
    Action,
    Command,
    DeclareVehicle,
    Dropped,
    EmergencyRequest,
    Publish,
    SendMessage,
    ShutdownComplete,
    follow_up_query,
)
from edge_vis.kit.contract import (
    STATUS_NAMES,
    Binding,
    ClockView,
    HandoffView,
    HolderView,
    ReportSpec,
    TopicDecl,
    Translator,
    TranslatorContext,
    VehicleView,
    derive_vehicle_id,
)
from edge_vis.kit.imagery import CHUNK_BYTES, image_chunks, publish_image
from edge_vis.kit.lists import (
    ELEMENTS_PER_SET,
    LIST_REPLIES,
    LIST_REPORTS,
    QUERIES_IN_FLIGHT,
    HeldList,
    ListDriver,
    ListLoad,
    ListLoader,
    ListReadBack,
    list_bindings,
    providers,
)
from edge_vis.kit.rules import (
    NAN,
    Build,
    CommandRule,
    Computed,
    Const,
    Each,
    From,
    Put,
    PutEach,
    ReportRule,
    RuleTranslator,
    Spec,
    clamp,
    code_of,
    declarations,
    decode_as,
    describe_rules,
    extract,
    flags,
    get_path,
    label,
    number,
    path_problem,
    put,
    resolve_path,
    set_path,
)
from edge_vis.schema import read_table, setting

__all__ = [
    "CHUNK_BYTES",
    "ELEMENTS_PER_SET",
    "LIST_REPLIES",
    "LIST_REPORTS",
    "NAN",
    "QUERIES_IN_FLIGHT",
    "STATUS_NAMES",
    "Action",
    "Binding",
    "Build",
    "ClockView",
    "Command",
    "CommandRule",
    "Computed",
    "ConfigError",
    "Const",
    "DeclareVehicle",
    "DecodeError",
    "Dropped",
    "Each",
    "EmergencyRequest",
    "EncodeError",
    "From",
    "HandoffView",
    "HeldList",
    "HolderView",
    "JausAddress",
    "ListDriver",
    "ListLoad",
    "ListLoader",
    "ListReadBack",
    "Publish",
    "Put",
    "PutEach",
    "ReportRule",
    "ReportSpec",
    "RuleTranslator",
    "SendMessage",
    "ShutdownComplete",
    "Spec",
    "TopicDecl",
    "Translator",
    "TranslatorContext",
    "VehicleView",
    "clamp",
    "code_of",
    "declarations",
    "decode_as",
    "derive_vehicle_id",
    "describe_rules",
    "extract",
    "flags",
    "follow_up_query",
    "get_path",
    "image_chunks",
    "label",
    "list_bindings",
    "number",
    "path_problem",
    "providers",
    "publish_image",
    "put",
    "read_table",
    "resolve_path",
    "set_path",
    "setting",
]
