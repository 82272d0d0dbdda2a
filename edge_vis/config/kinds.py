"""Which kind of profile a TOML file is, told from its keys and its folder. No I/O.

Four kinds of TOML file configure edge-vis, each with its own schema:

* a *deployment profile* (``profiles/default.toml``, ``deploy/relay.toml``): one relay,
  :class:`~edge_vis.config.RelayProfile`;
* a *vehicle profile* (``profiles/vehicles/*.toml``): one vehicle known in advance,
  :class:`~edge_vis.config.VehicleProfile`;
* a *sim profile* (``profiles/sim/*.toml``): simulated vehicles,
  :class:`~edge_vis.tools.sim.profile.SimProfile`;
* a *link profile* (``profiles/links/*.toml``, ``edge_vis/data/links/*.toml``): a radio
  medium, :class:`~edge_vis.bandwidth.linkspec.LinkSpec`.

The top-level keys tell them apart: each kind has keys no other has (``[relay]``,
``vehicle_id``, ``seed``, ``bit_rate``...), ``[[vehicles]]`` entries of a deployment
have ``vehicle_id`` or ``file`` where a sim's have ``name``, and a ``[discovery]`` table
holds a deployment's timing (``period``...) or how a vehicle is found (``hello``...).
When the keys do not tell (an empty file, only keys two kinds share, or keys of two kinds
mixed), the folder decides if it names one of the candidates (``sim``, ``vehicles``,
``links``).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import PurePath
from typing import Any

from edge_vis.bandwidth.linkspec import SPEC_KEYS
from edge_vis.config.deployment import RelayProfile
from edge_vis.config.vehicles import VehicleDiscovery, VehicleProfile
from edge_vis.schema import toml_keys

DEPLOYMENT = "deployment"
VEHICLE = "vehicle"
SIM = "sim"
LINK = "link"
KINDS: tuple[str, ...] = (DEPLOYMENT, VEHICLE, SIM, LINK)

#: the top-level keys of each kind, as their schemas declare them (the sim profile's live
#: with the simulator, which config does not import; a test holds them equal)
KEYS: Mapping[str, frozenset[str]] = {
    DEPLOYMENT: toml_keys(RelayProfile) | {"access"},
    VEHICLE: toml_keys(VehicleProfile) | {"address", "services"},
    SIM: frozenset({"seed", "vehicles"}),
    LINK: SPEC_KEYS,
}

#: what a file of each kind looks like, for a message that cannot tell
LOOKS: Mapping[str, str] = {
    DEPLOYMENT: "[relay], [links.NAME], [dds], [translators], ... (profiles/*.toml)",
    VEHICLE: "vehicle_id = ... (profiles/vehicles/*.toml)",
    SIM: "[[vehicles]] with name, subsystem and link (profiles/sim/*.toml)",
    LINK: "bit_rate = ... (profiles/links/*.toml)",
}

#: folder name -> the kind of profile it holds
FOLDERS: Mapping[str, str] = {"sim": SIM, "vehicles": VEHICLE, "links": LINK}


def profile_kind(data: Mapping[str, Any], path: str | PurePath = "") -> tuple[str | None, str]:
    """``(kind, "")``, or ``(None, why it cannot tell)`` for parsed TOML ``data``."""
    marks = {kind: sorted(_marks(kind, data)) for kind in KINDS}
    candidates = [kind for kind in KINDS if marks[kind]]
    folder = FOLDERS.get(PurePath(path).parent.name) if path else None
    if len(candidates) == 1:
        return candidates[0], ""
    if len(candidates) > 1:
        if folder in candidates:
            return folder, ""
        mixed = " and ".join(f"a {kind} profile ({', '.join(marks[kind])})"
                             for kind in candidates)
        return None, f"its keys are those of {mixed}"
    if folder is not None:
        return folder, ""
    shared = sorted(set(data))
    if shared:
        return None, (f"its keys ({', '.join(shared)}) belong to more than one kind and its "
                      f"folder is none of {', '.join(FOLDERS)}")
    return None, f"it is empty and its folder is none of {', '.join(FOLDERS)}"


def expected_kinds() -> str:
    """One line per kind: what a file of that kind looks like."""
    return "\n".join(f"  {kind} profile: {LOOKS[kind]}" for kind in KINDS)


def _marks(kind: str, data: Mapping[str, Any]) -> set[str]:
    """The keys of ``data`` that only ``kind`` has (``vehicles`` by what its entries hold)."""
    others = frozenset().union(*(KEYS[k] for k in KINDS if k != kind))
    found = {key for key in data if key in KEYS[kind] and key not in others}
    entries = data.get("vehicles")
    if isinstance(entries, list) and entries and all(isinstance(e, Mapping) for e in entries):
        if kind == DEPLOYMENT and all("vehicle_id" in e or "file" in e for e in entries):
            found.add("[[vehicles]] with vehicle_id")
        if kind == SIM and all("name" in e and "vehicle_id" not in e for e in entries):
            found.add("[[vehicles]] with name")
    # [discovery] is a deployment's timing, or how a vehicle is found: its keys tell
    table = data.get("discovery")
    if isinstance(table, Mapping) and table:
        vehicle_keys = toml_keys(VehicleDiscovery)
        if kind == VEHICLE and all(key in vehicle_keys for key in table):
            found.add("[discovery] with hello or passive")
        if kind == DEPLOYMENT and not any(key in vehicle_keys for key in table):
            found.add("[discovery] with period")
    return found
