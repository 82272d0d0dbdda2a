"""DDS QoS per topic kind, and why. No I/O (builds Cyclone QoS objects only).

=========  ===========  ===============  ====================  ===========================
kind       reliability  durability       history               extra
=========  ===========  ===============  ====================  ===========================
TELEMETRY  best-effort  volatile         keep-last 1           --
STATE      reliable     transient-local  keep-last 1           --
COMMAND    reliable     volatile         keep-last 8           lifespan 500 ms
EMERGENCY  reliable     volatile         keep-all              --
PRODUCT    reliable     transient-local  keep-all              --
BULK       reliable     volatile         keep-all              max blocking 2 s
=========  ===========  ===============  ====================  ===========================

Why:

* **Telemetry** (poses, velocities, scans) is periodic and superseded by the next sample:
  retransmitting an old pose only delays the new one, so best-effort; keep-last 1 *per
  instance*, i.e. per vehicle, so a slow reader sees the newest pose of every vehicle and
  never a backlog.
* **State** (identification, status, control, mission, link, health) changes rarely and a
  missed change would stay wrong until the next one: reliable. Transient-local with
  keep-last 1 makes each writer keep the latest sample per vehicle and hand it to readers
  that join later, so an operator station started after the relay sees every vehicle at once.
* **Commands** must arrive (reliable) but must not act late: a velocity command that waited
  in a queue for seconds is dangerous. The writer sets a lifespan (``command_lifespan``,
  default 0.5 s); Cyclone drops a sample from the reader's cache once it has waited there
  longer than that, so a relay that falls behind never executes stale commands. Cyclone
  counts the lifespan from when the sample *arrived*, not from its source time stamp, so
  clock offsets between hosts do not matter; network delay is not covered (the bridge's
  ``max_command_age`` option covers it when the clocks are synchronised). Volatile: a
  relay that restarts must not replay old commands. Keep-last 8 per vehicle so a burst
  (e.g. a control request followed at once by a command) is not collapsed.
* **Emergency stops** (``EmergencyCommand``) must arrive however late: a stop that waited
  is still a stop, and a CLEAR is checked against the rules when it arrives. Reliable,
  keep-all, no lifespan; volatile so a restarted relay does not replay them.
* **Image products** (metadata of ATR images) are few, and every one matters to every
  reader including late joiners: reliable, transient-local, keep-all. Memory grows with the
  number of products; dispose products that are no longer of interest.
* **Bulk** image chunks: reliable keep-all gives ordered, complete delivery with flow
  control; a writer blocks up to ``bulk_max_blocking`` when readers fall behind. Not kept
  for late joiners (they fetch a product again if they need it).

Readers use the same QoS as writers (a reliable reader of a best-effort writer would not
match; a volatile reader of a transient-local writer would miss the history).
"""

from __future__ import annotations

from dataclasses import dataclass

from cyclonedds.qos import Policy, Qos
from cyclonedds.util import duration

from edge_vis.dds.topics import TopicKind


@dataclass(frozen=True, slots=True)
class QosSettings:
    """The tunable numbers of the QoS profiles, in seconds or samples."""

    command_lifespan: float = 0.5
    """How long a command may wait in a reader before it is dropped unread."""
    command_depth: int = 8
    """Commands kept per vehicle and topic."""
    reliable_max_blocking: float = 0.1
    """How long a reliable write may block when the history is full."""
    bulk_max_blocking: float = 2.0
    """How long a bulk (image chunk) write may block for slow readers."""

    def __post_init__(self) -> None:
        if self.command_lifespan <= 0:
            raise ValueError(f"command_lifespan must be > 0 s, got {self.command_lifespan}")
        if self.command_depth < 1:
            raise ValueError(f"command_depth must be >= 1, got {self.command_depth}")
        if self.reliable_max_blocking < 0 or self.bulk_max_blocking < 0:
            raise ValueError("max blocking times must be >= 0 s")


def topic_qos(kind: TopicKind, settings: QosSettings | None = None) -> Qos:
    """The QoS for readers and writers of a topic of ``kind`` (see the module table)."""
    s = settings or QosSettings()
    reliable = Policy.Reliability.Reliable(duration(seconds=s.reliable_max_blocking))
    if kind is TopicKind.TELEMETRY:
        return Qos(
            Policy.Reliability.BestEffort,
            Policy.Durability.Volatile,
            Policy.History.KeepLast(1),
        )
    if kind is TopicKind.STATE:
        return Qos(reliable, Policy.Durability.TransientLocal, Policy.History.KeepLast(1))
    if kind is TopicKind.COMMAND:
        return Qos(
            reliable,
            Policy.Durability.Volatile,
            Policy.History.KeepLast(s.command_depth),
            Policy.Lifespan(duration(seconds=s.command_lifespan)),
        )
    if kind is TopicKind.EMERGENCY:
        return Qos(reliable, Policy.Durability.Volatile, Policy.History.KeepAll)
    if kind is TopicKind.PRODUCT:
        return Qos(reliable, Policy.Durability.TransientLocal, Policy.History.KeepAll)
    if kind is TopicKind.BULK:
        return Qos(
            Policy.Reliability.Reliable(duration(seconds=s.bulk_max_blocking)),
            Policy.Durability.Volatile,
            Policy.History.KeepAll,
        )
    raise ValueError(f"no QoS for topic kind {kind!r}")


def partition_qos(partitions: tuple[str, ...]) -> Qos | None:
    """Publisher/subscriber QoS placing entities in ``partitions`` (None: the default one)."""
    if not partitions:
        return None
    return Qos(Policy.Partition(list(partitions)))
