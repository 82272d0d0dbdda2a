"""Cyclone DDS XML configurations edge-vis ships. No I/O.

Cyclone reads its configuration when a process creates the first participant of a domain,
from the ``config`` a :class:`~edge_vis.dds.bridge.DdsBridge` is given or else from the
``CYCLONEDDS_URI`` environment variable (XML text or ``file://`` URL). Without either it
uses multicast discovery on the first suitable network interface, which is what a relay on
a LAN normally wants.

:func:`loopback_config` is for a single host with no usable multicast, such as a test
sandbox or a relay whose operator station runs on the same computer:

* ``NetworkInterface address="127.0.0.1"`` keeps all traffic on the loopback interface;
* ``AllowMulticast false`` because Linux loopback carries no multicast;
* unicast discovery to the ``Peer`` 127.0.0.1: Cyclone then probes the discovery ports of
  participant indices 0..``MaxAutoParticipantIndex`` on that address, so at most that many
  + 1 participants per domain can find each other on the host (default 31);
* ``ParticipantIndex auto`` gives each participant its own port.
"""

from __future__ import annotations

_LOOPBACK = """<CycloneDDS><Domain id="any">
<General><Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces>
<AllowMulticast>false</AllowMulticast></General>
<Discovery><ParticipantIndex>auto</ParticipantIndex>
<MaxAutoParticipantIndex>{max_index}</MaxAutoParticipantIndex>
<Peers><Peer address="127.0.0.1"/></Peers></Discovery>
</Domain></CycloneDDS>"""


def loopback_config(max_participants: int = 32) -> str:
    """Cyclone XML for discovery and data on 127.0.0.1 only (see the module docstring)."""
    if not 1 <= max_participants <= 120:
        raise ValueError(f"max_participants must be 1..120, got {max_participants}")
    return _LOOPBACK.format(max_index=max_participants - 1).replace("\n", "")
