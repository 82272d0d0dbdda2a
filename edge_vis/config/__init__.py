"""Profiles: TOML -> validated frozen dataclasses. The public import surface of config.

* :mod:`~edge_vis.config.deployment` - the deployment profile's schema (:class:`RelayProfile`
  and its sections, :class:`LinkProfile`, :class:`TranslatorSelection`, ...);
* :mod:`~edge_vis.config.vehicles` - vehicle profiles (inline or files of their own);
* :mod:`~edge_vis.config.report_rates` - ``[report_rates]`` entries;
* :mod:`~edge_vis.config.operators` - who may request control;
* :mod:`~edge_vis.config.loader` - reading profile files and the files they reference;
* :mod:`~edge_vis.config.kinds` - which kind of profile a TOML file is (``edge-vis check``).

The dataclasses are the schema: the validation kit (:mod:`edge_vis.schema`) reads a file
against them, so a setting's default, type and range are written once, on its field.
Every problem is reported as ``(file, key path, reason)`` in one
:class:`~edge_vis.errors.ConfigError`.
"""

from __future__ import annotations

from edge_vis.config.deployment import (
    AccessProfile,
    BulkProfile,
    CommandProfile,
    ControlProfile,
    DdsProfile,
    DdsSecurityProfile,
    DiscoveryProfile,
    EmergencyProfile,
    EventsProfile,
    LimitsProfile,
    LinkProfile,
    OperatorEntry,
    RelayProfile,
    RoutingProfile,
    ServingProfile,
    TimeProfile,
    TranslatorSelection,
)
from edge_vis.config.loader import (
    default_profile_path,
    from_mapping,
    link_problems,
    load_default_profile,
    load_profile,
    load_vehicle_profile,
    read_deployment,
    read_profile_file,
    read_toml,
)
from edge_vis.config.operators import OperatorPolicy
from edge_vis.config.report_rates import DEFAULT_MINIMUM_SHARE, DEFAULT_REPORT_PRIORITY, ReportRate
from edge_vis.config.vehicles import ComponentProfile, ServiceProfile, VehicleProfile

__all__ = [
    "DEFAULT_MINIMUM_SHARE", "DEFAULT_REPORT_PRIORITY", "AccessProfile", "BulkProfile",
    "CommandProfile", "ComponentProfile", "ControlProfile", "DdsProfile", "DdsSecurityProfile",
    "DiscoveryProfile",
    "EmergencyProfile",
    "EventsProfile", "LimitsProfile", "LinkProfile", "OperatorEntry", "OperatorPolicy",
    "RelayProfile", "ReportRate", "RoutingProfile", "ServiceProfile", "ServingProfile",
    "TimeProfile",
    "TranslatorSelection",
    "VehicleProfile",
    "default_profile_path", "from_mapping", "link_problems", "load_default_profile",
    "load_profile", "load_vehicle_profile", "read_deployment", "read_profile_file", "read_toml",
]
