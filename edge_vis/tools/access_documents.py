"""The DDS Security governance and permissions documents of a deployment. No I/O.

Governance (one per deployment, every participant loads the same): nobody joins without
an identity from the deployment CA, every topic needs read and write permission, and
discovery, liveliness, metadata and data are encrypted.

Permissions (one per identity, naming its certificate's subject), default DENY:

* a **relay** publishes any topic in the relay's partitions (vehicle topics are the
  relays' alone), reads the command topics in the operator partitions and the other
  relays' ``RelayStatus`` (:mod:`edge_vis.engine.duty`);
* an **operator** publishes the command topics only in its own partition
  (:func:`~edge_vis.config.deployment.operator_partition`), so the partition a command
  arrives in proves who wrote it, and reads every topic in the relay's partitions;
* an **observer** (a monitor, a display) only reads.

A rule without ``<partitions>`` covers only the default partition, which is where a
relay without ``[dds] partitions`` publishes.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from xml.sax.saxutils import escape

from edge_vis.config.deployment import OPERATOR_PARTITION_PREFIX, operator_partition

RELAY, OPERATOR, OBSERVER = "relay", "operator", "observer"
ROLES = (RELAY, OPERATOR, OBSERVER)

_HEAD = ('<?xml version="1.0" encoding="UTF-8"?>\n<dds xmlns:xsi='
         '"http://www.w3.org/2001/XMLSchema-instance" xsi:noNamespaceSchemaLocation='
         '"http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_{what}.xsd">\n')


def governance_xml(domain: int) -> str:
    """The governance document for DDS domain ``domain``."""
    return _HEAD.format(what="governance") + f"""\
  <domain_access_rules>
    <domain_rule>
      <domains><id>{domain}</id></domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>NONE</rtps_protection_kind>
      <topic_access_rules>
        <topic_rule>
          <topic_expression>*</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>true</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>
          <data_protection_kind>ENCRYPT</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
"""


@dataclass(frozen=True, slots=True)
class Grant:
    """Who (certificate subject), in which role, from when to when (``YYYY-MM-DDThh:mm:ss``).

    ``name`` is the relay name or operator id; ``partitions`` the relays' DDS partitions
    (empty: the default partition); ``commands`` the command topics.
    """

    subject: str
    role: str
    name: str
    not_before: str
    not_after: str


def _criteria(kind: str, topics: Iterable[str], partitions: Sequence[str]) -> str:
    lines = [f"      <{kind}>", "        <topics>"]
    lines += [f"          <topic>{escape(t)}</topic>" for t in topics]
    lines.append("        </topics>")
    if partitions:
        lines.append("        <partitions>")
        lines += [f"          <partition>{escape(p)}</partition>" for p in partitions]
        lines.append("        </partitions>")
    lines.append(f"      </{kind}>")
    return "\n".join(lines) + "\n"


def permissions_xml(grants: Iterable[Grant], domain: int, partitions: Sequence[str],
                    commands: Sequence[str]) -> str:
    """A permissions document holding ``grants`` (one per identity; see the module)."""
    body = ""
    for grant in grants:
        if grant.role == RELAY:
            rules = (_criteria("publish", ["*"], partitions)
                     + _criteria("subscribe", commands, [f"{OPERATOR_PARTITION_PREFIX}*"])
                     # relays sharing the domain read each other's RelayStatus
                     + _criteria("subscribe", ["RelayStatus"], partitions))
        elif grant.role == OPERATOR:
            rules = (_criteria("publish", commands, [operator_partition(grant.name)])
                     + _criteria("subscribe", ["*"], partitions))
        elif grant.role == OBSERVER:
            rules = _criteria("subscribe", ["*"], partitions)
        else:
            raise ValueError(f"unknown role {grant.role!r} (expected one of {ROLES})")
        body += f"""\
    <grant name="{escape(grant.role)}.{escape(grant.name)}">
      <subject_name>{escape(grant.subject)}</subject_name>
      <validity>
        <not_before>{grant.not_before}</not_before>
        <not_after>{grant.not_after}</not_after>
      </validity>
      <allow_rule>
      <domains><id>{domain}</id></domains>
{rules}      </allow_rule>
      <default>DENY</default>
    </grant>
"""
    return _HEAD.format(what="permissions") + f"  <permissions>\n{body}  </permissions>\n</dds>\n"


__all__ = ["OBSERVER", "OPERATOR", "RELAY", "ROLES", "Grant", "governance_xml",
           "permissions_xml"]
