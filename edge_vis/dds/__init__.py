"""The DDS side of edge-vis, on Cyclone DDS: data model, QoS, and the bridge.

This package is the only part of the core that imports ``cyclonedds`` (install the
``dds`` extra). Its modules:

* :mod:`~edge_vis.dds.model` -- the IdlStruct types of the UCS-MDE-style model (no I/O);
  the same model ships as IDL, printed by ``edge-vis idl``;
* :mod:`~edge_vis.dds.topics` -- :class:`TopicSpec`, :class:`TopicKind`,
  :class:`TopicRegistry` (no I/O);
* :mod:`~edge_vis.dds.qos` -- QoS per topic kind and why (no I/O);
* :mod:`~edge_vis.dds.convert` -- checked dict <-> sample conversion (no I/O);
* :mod:`~edge_vis.dds.bridge` -- :class:`DdsBridge`, the participant (I/O);
* :mod:`~edge_vis.dds.cyclone_config` -- Cyclone XML such as :func:`loopback_config`;
* :mod:`~edge_vis.dds.secure_qos` -- DDS Security as participant QoS (no I/O);
* :mod:`~edge_vis.dds.binding` -- what differs between the 11.x and 0.10.2 bindings.
"""

from __future__ import annotations

try:
    import cyclonedds  # noqa: F401
except ImportError as exc:  # pragma: no cover - depends on the installation
    raise ImportError(
        "edge_vis.dds needs Cyclone DDS; install it with: pip install 'edge-vis[dds]'"
    ) from exc

from edge_vis.dds.bridge import DdsBridge, DdsError, TopicReader
from edge_vis.dds.convert import converter_for, key_members
from edge_vis.dds.cyclone_config import loopback_config
from edge_vis.dds.qos import QosSettings, topic_qos
from edge_vis.dds.topics import TopicKind, TopicRegistry, TopicSpec, standard_topics

__all__ = [
    "DdsBridge",
    "DdsError",
    "QosSettings",
    "TopicKind",
    "TopicReader",
    "TopicRegistry",
    "TopicSpec",
    "converter_for",
    "key_members",
    "loopback_config",
    "standard_topics",
    "topic_qos",
]
