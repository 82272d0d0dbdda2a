"""The DDS side of a relay: one Cyclone participant, writers per topic, command readers. I/O.

:class:`DdsBridge` turns ``Publish(topic, sample_dict)`` actions into DDS writes and DDS
command samples into ``(topic, dict)`` deliveries. Converting and checking dicts is
:mod:`edge_vis.dds.convert`; the QoS per topic kind is :mod:`edge_vis.dds.qos`.

Life cycle::

    DdsBridge(...)                          participant, publisher, subscriber exist
      -> (open_writers | publish | dispose | unregister | subscribe | take | reader)*
      -> close()                            idempotent; also on ``with`` exit

Delivery of received samples, two ways:

* ``subscribe(names, on_sample, loop=loop)``: one delivery thread per bridge blocks in a
  Cyclone WaitSet (no polling, no busy loop) and, when samples arrive, takes them, converts
  them to dicts and hands each batch to ``loop.call_soon_threadsafe`` so ``on_sample(topic,
  dict)`` runs in the asyncio loop. Without ``loop`` the callback runs in the delivery
  thread and must be thread-safe. Latency is one thread wake-up plus one loop iteration.
* ``subscribe(names)`` without a callback: samples wait in the readers' caches until
  :meth:`DdsBridge.take` polls them (non-blocking; suitable for a loop that polls anyway).

:meth:`DdsBridge.reader` gives operator-side tools (monitor, tests) a :class:`TopicReader`
for any topic, with blocking ``take(timeout)`` and non-destructive ``read``.

DDS Security (``security=``, :mod:`edge_vis.dds.secure_qos`): the participant joins with
a certificate and signed permissions. ``writer_partitions`` puts the writers in other
partitions than the readers (an operator writes commands in its own partition and reads
the relay's), and ``subscribe(..., partition=P)`` reads topics in partition ``P`` alone,
so the relay can tell whose partition a command came from.

Threads: ``publish`` may be called from any one thread at a time; callbacks come from the
delivery thread or the given loop.
"""

from __future__ import annotations

import asyncio
import logging
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from cyclonedds.core import (
    DDSException,
    GuardCondition,
    InstanceState,
    ReadCondition,
    SampleState,
    ViewState,
    WaitSet,
)
from cyclonedds.domain import Domain, DomainParticipant
from cyclonedds.pub import DataWriter, Publisher
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader, Subscriber
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from edge_vis.config.deployment import DdsSecurityProfile
from edge_vis.dds.binding import (
    MatchListener,
    match_listener,
    matched_publications,
    matched_subscriptions,
    unsigned_handle,
)
from edge_vis.dds.convert import Converter, converter_for, key_members
from edge_vis.dds.qos import QosSettings, partition_qos, topic_qos
from edge_vis.dds.secure_qos import HOW_TO_SECURE, participant_qos, security_available
from edge_vis.dds.topics import TopicKind, TopicRegistry, TopicSpec
from edge_vis.errors import EdgeVisError, LinkError

log = logging.getLogger(__name__)

OnSample = Callable[[str, dict[str, Any]], object]
"""Receives ``(topic name, sample dict)``."""

_ANY_SAMPLE = SampleState.Any | ViewState.Any | InstanceState.Any
_BATCH = 256
_RETCODE_PRECONDITION_NOT_MET = -4
#: writers (publication handles) remembered per operator for :meth:`DdsBridge.watch_writers`
MAX_WATCHED_WRITERS = 1024
#: seconds between two checks of which watched writers still match
WRITER_CHECK_PERIOD = 0.1
#: batches handed to the event loop and not yet delivered; past it the delivery thread
#: waits, and samples stay in the readers' bounded histories (commands: newest 8)
MAX_IN_FLIGHT = 64
#: image products (and their bulk data) kept per topic for late joiners before the oldest
#: is disposed: keep-all transient-local history would otherwise grow with every image
MAX_PRODUCTS = 256
_RETIRED_KINDS = (TopicKind.PRODUCT, TopicKind.BULK)


# an instance handle unsigned: the 11.x binding gives a sample's ``publication_handle``
# unsigned but ``get_matched_publications()`` signed, so about half the writers (top bit
# set) would never be found matched and be taken for gone
_handle = unsigned_handle

# Domains created with an explicit configuration live as long as the process: deleting a
# Cyclone domain deletes every participant in it, including other bridges'.
_DOMAINS: dict[int, Domain] = {}
_DOMAINS_LOCK = threading.Lock()


class DdsError(LinkError):
    """A DDS operation failed (participant creation, write timeout, ...)."""


@dataclass(slots=True)
class _Subscription:
    spec: TopicSpec
    reader: DataReader[Any]
    condition: ReadCondition
    converter: Converter
    on_sample: OnSample | None
    loop: asyncio.AbstractEventLoop | None
    partition: str | None = None
    matches: MatchListener | None = None


def _ensure_domain(domain_id: int, config: str) -> None:
    with _DOMAINS_LOCK:
        if domain_id in _DOMAINS:
            return
        try:
            _DOMAINS[domain_id] = Domain(domain_id, config)
        except DDSException as exc:
            if exc.code != _RETCODE_PRECONDITION_NOT_MET:
                raise DdsError(f"cannot configure DDS domain {domain_id}: {exc}") from exc
            log.warning(
                "DDS domain %d already exists in this process; its configuration stays", domain_id
            )


class DdsBridge:
    """One DDS participant of a relay (or of an operator-side tool).

    ``domain_id``: DDS domain. ``partitions``: DDS partitions for all writers and readers
    (empty: the default partition). ``topics``: the topic registry (default: the standard
    model). ``qos``: QoS tuning. ``config``: Cyclone XML or ``file://`` URL for the domain
    (default: ``CYCLONEDDS_URI`` or Cyclone's defaults; see
    :mod:`edge_vis.dds.cyclone_config`). ``max_command_age``: if set (seconds), command
    samples whose source time stamp is older are dropped and counted; only meaningful with
    synchronised clocks (NTP/PTP) between operator stations and the relay.
    ``max_products``: instances of each product/bulk topic (one per image) kept; past it
    the oldest is disposed and unregistered (counted as ``products_retired``).
    ``security``: join with DDS Security (certificate, signed governance and permissions).
    ``writer_partitions``: partitions of the writers when not ``partitions``.

    Raises :class:`DdsError` if the participant cannot be created (with ``security``: also
    when its files are refused or the binding has no DDS Security).
    """

    def __init__(
        self,
        domain_id: int = 0,
        partitions: Iterable[str] = (),
        topics: TopicRegistry | Iterable[TopicSpec] | None = None,
        *,
        qos: QosSettings | None = None,
        config: str | None = None,
        max_command_age: float | None = None,
        max_products: int = MAX_PRODUCTS,
        security: DdsSecurityProfile | None = None,
        writer_partitions: Iterable[str] | None = None,
    ) -> None:
        if topics is None:
            registry = TopicRegistry.standard()
        elif isinstance(topics, TopicRegistry):
            registry = topics
        else:
            registry = TopicRegistry(topics)
        self.registry = registry
        self.domain_id = domain_id
        self.partitions = tuple(partitions)
        self.writer_partitions = (self.partitions if writer_partitions is None
                                  else tuple(writer_partitions))
        self.secure = security is not None
        self.qos_settings = qos or QosSettings()
        self.max_command_age = max_command_age
        # Compile every converter now so a bad plugin type fails at start-up, not mid-run.
        self._converters = {spec.name: converter_for(spec.type) for spec in registry}
        if config is not None:
            _ensure_domain(domain_id, config)
        if security is not None and not security_available():
            raise DdsError(f"cannot join DDS domain {domain_id} securely: {HOW_TO_SECURE}")
        try:
            self._participant = DomainParticipant(
                domain_id, qos=participant_qos(security) if security is not None else None)
        except DDSException as exc:
            what = " with DDS Security (certificate, key, governance or permissions " \
                   "refused; see the log above)" if security is not None else ""
            raise DdsError(f"cannot join DDS domain {domain_id}{what}: {exc}") from exc
        try:
            self._publisher = Publisher(self._participant,
                                        qos=partition_qos(self.writer_partitions))
            self._subscriber = Subscriber(self._participant, qos=partition_qos(self.partitions))
            #: subscribers of single partitions (subscribe(partition=...))
            self._partition_subscribers: dict[str, Subscriber] = {}
            self._guard = GuardCondition(self._participant)
            self._waitset = WaitSet(self._participant)
            self._waitset.attach(self._guard)
        except DDSException as exc:
            raise DdsError(f"cannot join DDS domain {domain_id}: {exc}") from exc
        self._topics: dict[str, Topic[Any]] = {}
        self._writers: dict[str, DataWriter[Any]] = {}
        self._writer_matches: dict[str, MatchListener | None] = {}
        self._subscriptions: tuple[_Subscription, ...] = ()
        self._readers: list[TopicReader] = []
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._closed = False
        self.counters: dict[str, int] = {
            "published": 0,
            "received": 0,
            "stale_dropped": 0,
            "callback_errors": 0,
            "handover_waits": 0,
            "products_retired": 0,
        }
        self.max_products = max_products
        self._products: dict[str, dict[tuple[Any, ...], None]] = {}
        #: vehicle id -> (topic, key values) of the instances written for it (withdraw)
        self._instances: dict[str, set[tuple[str, tuple[Any, ...]]]] = {}
        self._key_names: dict[str, tuple[str, ...]] = {}
        self._in_flight = threading.Semaphore(MAX_IN_FLIGHT)
        #: publication handle -> operator_id of the commands it wrote (watch_writers)
        self._writers_of: dict[int, str] = {}
        self._on_writer_gone: Callable[[str], object] | None = None
        self._gone_loop: asyncio.AbstractEventLoop | None = None
        self._writers_checked = 0.0

    # ------------------------------------------------------------------ writing

    def spec(self, topic: str) -> TopicSpec:
        """The registered spec of ``topic`` (``KeyError`` listing known topics)."""
        return self.registry.get(topic)

    def _converter(self, name: str) -> Converter:
        converter = self._converters.get(name)
        if converter is None:  # registered after the bridge was made
            converter = self._converters[name] = converter_for(self.registry.get(name).type)
        return converter

    def _topic(self, name: str) -> Topic[Any]:
        topic = self._topics.get(name)
        if topic is None:
            spec = self.registry.get(name)
            topic = Topic(self._participant, spec.name, spec.type)
            self._topics[name] = topic
        return topic

    def _writer(self, name: str) -> DataWriter[Any]:
        writer = self._writers.get(name)
        if writer is None:
            self._check_open()
            spec = self.registry.get(name)
            qos = topic_qos(spec.kind, self.qos_settings)
            listener = self._writer_matches[name] = match_listener()
            try:
                writer = DataWriter(self._publisher, self._topic(name), qos=qos,
                                    listener=listener)
            except DDSException as exc:  # e.g. NOT_ALLOWED_BY_SECURITY: not in permissions
                raise DdsError(f"cannot create a writer of {name!r}: {exc}") from exc
            self._writers[name] = writer
        return writer

    def open_writers(self, topics: Iterable[str]) -> None:
        """Create the writers of ``topics`` now, so readers can discover them early.

        Writers are otherwise created at the first :meth:`publish`; samples of a volatile
        topic written before a reader has matched are not delivered to it.
        """
        for name in topics:
            self._writer(name)

    def publish(self, topic: str, sample: Mapping[str, Any]) -> None:
        """Convert ``sample`` to ``topic``'s type and write it.

        Raises ``KeyError`` for an unknown topic, :class:`~edge_vis.errors.EncodeError`
        naming topic and member for a bad dict, :class:`DdsError` if the write fails (for
        instance a reliable write blocked longer than the QoS allows).
        """
        writer = self._writers.get(topic) or self._writer(topic)
        data = self._converter(topic).to_struct(sample, topic)
        try:
            writer.write(data)
        except DDSException as exc:
            raise DdsError(f"writing {topic!r} failed: {exc}") from exc
        self.counters["published"] += 1
        spec = self.registry.get(topic)
        if spec.kind in _RETIRED_KINDS:
            self._retire_old(spec, sample)
        vehicle_id = sample.get("vehicle_id")
        if vehicle_id:
            names = self._key_names.get(topic)
            if names is None:
                names = self._key_names[topic] = key_members(spec.type)
            self._instances.setdefault(str(vehicle_id), set()).add(
                (topic, tuple(sample.get(k) for k in names)))

    def withdraw(self, vehicle_id: str) -> int:
        """Unregister every instance this participant wrote for ``vehicle_id``: another
        relay writes them now, so readers see one writer per instance and late joiners
        do not get this relay's last state. Returns how many were unregistered."""
        done = 0
        for topic, key in sorted(self._instances.pop(vehicle_id, set()), key=repr):
            try:
                self.unregister(topic, dict(zip(self._key_names[topic], key, strict=True)))
                done += 1
            except EdgeVisError as exc:
                log.warning("cannot withdraw %s %s: %s", topic, key, exc)
        self.counters["withdrawn"] = self.counters.get("withdrawn", 0) + done
        return done

    def _retire_old(self, spec: TopicSpec, sample: Mapping[str, Any]) -> None:
        """Bound the instances of a product topic: dispose the oldest past ``max_products``."""
        names = key_members(spec.type)
        key = tuple(sample.get(k) for k in names)
        live = self._products.setdefault(spec.name, {})
        live.pop(key, None)
        live[key] = None
        while len(live) > self.max_products:
            old = next(iter(live))
            del live[old]
            self.counters["products_retired"] += 1
            key_value = dict(zip(names, old, strict=True))
            try:
                self.dispose(spec.name, key_value)
                self.unregister(spec.name, key_value)
            except EdgeVisError as exc:
                log.warning("cannot retire %s %s: %s", spec.name, old, exc)

    def dispose(self, topic: str, key: Any) -> None:
        """Mark the instance ``key`` of ``topic`` as gone (e.g. a vehicle that left).

        ``key`` is the key value (``"ugv1"``) for single-key topics, else a dict of the key
        members. Readers see the instance as disposed; transient-local history drops it.
        """
        writer = self._writer(topic)
        try:
            writer.dispose(self._converter(topic).key_of(key, topic))
        except DDSException as exc:
            raise DdsError(f"disposing {key!r} on {topic!r} failed: {exc}") from exc

    def unregister(self, topic: str, key: Any) -> None:
        """Stop updating instance ``key`` of ``topic`` without declaring it gone."""
        writer = self._writer(topic)
        try:
            writer.unregister_instance(self._converter(topic).key_of(key, topic))
        except DDSException as exc:
            raise DdsError(f"unregistering {key!r} on {topic!r} failed: {exc}") from exc

    def matched_subscribers(self, topic: str) -> int:
        """How many readers (local or remote) currently match our writer of ``topic``."""
        writer = self._writer(topic)
        return matched_subscriptions(writer, self._writer_matches.get(topic))

    def wait_for_subscribers(self, topic: str, count: int = 1, timeout: float = 5.0) -> bool:
        """Wait until ``count`` readers match our writer of ``topic``; False on timeout.

        For start-up and tests: checks every 10 ms up to ``timeout`` seconds.
        """
        deadline = time.monotonic() + timeout
        while self.matched_subscribers(topic) < count:
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.01)
        return True

    # ------------------------------------------------------------------ reading

    def subscribe(
        self,
        topics: Iterable[str] | None = None,
        on_sample: OnSample | None = None,
        *,
        loop: asyncio.AbstractEventLoop | None = None,
        partition: str | None = None,
    ) -> None:
        """Read ``topics`` (default: every inbound/command topic of the registry).

        With ``on_sample`` the delivery thread calls it as ``on_sample(topic, dict)``, in
        ``loop`` if given (via ``call_soon_threadsafe``). Without it, poll with :meth:`take`.
        ``partition``: read these topics in that DDS partition only (not the bridge's),
        each partition with readers of its own.
        """
        self._check_open()
        if loop is not None and on_sample is None:
            raise ValueError("a loop only makes sense with an on_sample callback")
        names = list(self.registry.inbound() if topics is None else topics)
        specs = [self.registry.get(name) for name in names]  # KeyError before creating any
        added = []
        with self._lock:
            subscribed = {s.spec.name for s in self._subscriptions if s.partition == partition}
            twice = sorted({n for n in names if n in subscribed or names.count(n) > 1})
            if twice:
                raise ValueError(f"already subscribed: {', '.join(twice)}")
            subscriber = self._subscriber_of(partition)
            for spec in specs:
                qos = topic_qos(spec.kind, self.qos_settings)
                matches = match_listener()
                try:
                    reader = DataReader(subscriber, self._topic(spec.name), qos=qos,
                                        listener=matches)
                except DDSException as exc:
                    raise DdsError(f"cannot create a reader of {spec.name!r}: {exc}") from exc
                condition = ReadCondition(reader, _ANY_SAMPLE)
                converter = self._converter(spec.name)
                added.append(_Subscription(spec, reader, condition, converter, on_sample, loop,
                                           partition, matches))
            self._subscriptions += tuple(added)
        if on_sample is not None:
            for sub in added:
                self._waitset.attach(sub.condition)
            self._start_thread()
            self._guard.set(True)

    def _subscriber_of(self, partition: str | None) -> Subscriber:
        if partition is None:
            return self._subscriber
        subscriber = self._partition_subscribers.get(partition)
        if subscriber is None:
            subscriber = Subscriber(self._participant, qos=partition_qos((partition,)))
            self._partition_subscribers[partition] = subscriber
        return subscriber

    def watch_writers(self, on_gone: Callable[[str], object],
                      loop: asyncio.AbstractEventLoop | None = None) -> None:
        """Call ``on_gone(operator_id)`` (in ``loop`` if given) once every DDS writer that
        delivered a subscribed sample naming ``operator_id`` has gone away: the operator
        station died or closed. Checked by the delivery thread every
        :data:`WRITER_CHECK_PERIOD` s from the readers' matched publications, so it does not
        depend on the operator disposing anything."""
        self._on_writer_gone = on_gone
        self._gone_loop = loop

    def _check_writers(self) -> None:
        """Report operators none of whose writers match any reader any more."""
        writers = self._writers_of
        if not writers or self._on_writer_gone is None:
            return
        matched: set[int] = set()
        for sub in self._subscriptions:
            try:
                matched.update(matched_publications(sub.reader, sub.matches))
            except DDSException:
                return
        gone = {handle: op for handle, op in writers.items() if handle not in matched}
        if not gone:
            return
        for handle in gone:
            del writers[handle]
        alive = set(writers.values())
        for operator_id in sorted(set(gone.values()) - alive):
            log.info("operator %s: every DDS writer gone", operator_id)
            if self._gone_loop is not None:
                try:
                    self._gone_loop.call_soon_threadsafe(self._on_writer_gone, operator_id)
                except RuntimeError:  # the loop is closed
                    return
            else:
                self._call_gone(operator_id)

    def _call_gone(self, operator_id: str) -> None:
        try:
            assert self._on_writer_gone is not None
            self._on_writer_gone(operator_id)
        except Exception:
            self.counters["callback_errors"] += 1
            log.exception("writer-gone callback failed")

    def take(self, max_samples: int = _BATCH) -> list[tuple[str, dict[str, Any]]]:
        """Non-blocking: up to ``max_samples`` received ``(topic, dict)`` of the topics
        subscribed without a callback, oldest first per topic."""
        out: list[tuple[str, dict[str, Any]]] = []
        for sub in self._subscriptions:
            if sub.on_sample is None and len(out) < max_samples:
                out += self._take_from(sub, max_samples - len(out))
        return out

    def _take_from(self, sub: _Subscription, limit: int) -> list[tuple[str, dict[str, Any]]]:
        samples = sub.reader.take(N=limit, condition=sub.condition)
        out = []
        now_ns = time.time_ns()
        for sample in samples:
            info = sample.sample_info
            if not info.valid_data:
                continue  # an instance-state change (dispose, no writers), not data
            if (
                self.max_command_age is not None
                and sub.spec.kind is TopicKind.COMMAND
                and now_ns - info.source_timestamp > self.max_command_age * 1e9
            ):
                dropped = self.counters["stale_dropped"] = self.counters["stale_dropped"] + 1
                # first drop and every 100th at WARNING: an unsynchronised clock floods
                log.log(
                    logging.WARNING if dropped % 100 == 1 else logging.DEBUG,
                    "dropped a %s sample %.3f s old (limit %.3f s; %d dropped so far)",
                    sub.spec.name, (now_ns - info.source_timestamp) / 1e9, self.max_command_age,
                    dropped,
                )
                continue
            data = sub.converter.to_dict(sample)
            if self._on_writer_gone is not None and "operator_id" in data and (
                    len(self._writers_of) < MAX_WATCHED_WRITERS
                    or _handle(info.publication_handle) in self._writers_of):
                self._writers_of[_handle(info.publication_handle)] = str(data["operator_id"])
            out.append((sub.spec.name, data))
        self.counters["received"] += len(out)
        return out

    def reader(self, topic: str, *, depth: int | None = None) -> TopicReader:
        """A :class:`TopicReader` of ``topic`` with the topic's QoS (for tools and tests).

        ``depth`` keeps that many samples per instance instead of the topic's history: a
        reader that counts telemetry must not let one sample overwrite the last.
        """
        self._check_open()
        reader = TopicReader(self, self.registry.get(topic), depth=depth)
        self._readers.append(reader)
        return reader

    # ------------------------------------------------------------------ delivery thread

    def _start_thread(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(
                target=self._deliver_forever, name=f"edge-vis-dds-{self.domain_id}", daemon=True
            )
            self._thread.start()

    def _deliver_forever(self) -> None:
        while not self._closed:
            try:
                # watched writers are checked often; an idle relay sleeps
                self._waitset.wait(duration(seconds=WRITER_CHECK_PERIOD
                                            if self._writers_of else 1))
            except DDSException:
                if self._closed:
                    return
                raise
            self._guard.take()
            if self._closed:
                return
            for sub in self._subscriptions:
                if sub.on_sample is None:
                    continue
                while True:
                    batch = self._take_from(sub, _BATCH)
                    if batch:
                        self._hand_over(sub, batch)
                    if not sub.condition.is_triggered():
                        break
            if self._on_writer_gone is not None:
                now = time.monotonic()
                if now - self._writers_checked >= WRITER_CHECK_PERIOD:
                    self._writers_checked = now
                    self._check_writers()

    def _hand_over(self, sub: _Subscription, batch: list[tuple[str, dict[str, Any]]]) -> None:
        if sub.loop is None:
            self._call(sub.on_sample, batch)
            return
        if not self._in_flight.acquire(blocking=False):
            self.counters["handover_waits"] += 1  # the loop is behind: wait, bounded
            while not self._in_flight.acquire(timeout=0.5):
                if self._closed:
                    return
        try:
            sub.loop.call_soon_threadsafe(self._call_released, sub.on_sample, batch)
        except RuntimeError:  # the loop is closed: nobody is left to deliver to
            self._in_flight.release()
            log.warning("dropped %d %s sample(s): event loop closed", len(batch), sub.spec.name)

    def _call_released(self, on_sample: OnSample | None,
                       batch: list[tuple[str, dict[str, Any]]]) -> None:
        self._in_flight.release()
        self._call(on_sample, batch)

    def _call(self, on_sample: OnSample | None, batch: list[tuple[str, dict[str, Any]]]) -> None:
        assert on_sample is not None
        for topic, sample in batch:
            try:
                on_sample(topic, sample)
            except Exception:  # the shell keeps delivering; the failure is logged and counted
                self.counters["callback_errors"] += 1
                log.exception("on_sample callback failed for a %s sample", topic)

    # ------------------------------------------------------------------ shutdown

    def _check_open(self) -> None:
        if self._closed:
            raise DdsError("the DDS bridge is closed")

    def close(self) -> None:
        """Stop delivery and delete the participant and everything in it. Idempotent."""
        if self._closed:
            return
        self._closed = True
        self._guard.set(True)
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
        for reader in self._readers:
            reader.close()
        entities: list[Any] = [self._waitset]
        for sub in self._subscriptions:
            entities += [sub.condition, sub.reader]
        entities += list(self._writers.values())
        entities += list(self._topics.values())
        entities += [self._guard, self._publisher, self._subscriber,
                     *self._partition_subscribers.values(), self._participant]
        for entity in entities:
            _delete(entity)
        self._subscriptions = ()
        self._writers.clear()
        self._topics.clear()

    def __enter__(self) -> DdsBridge:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class TopicReader:
    """A reader of one topic that returns dicts; for operator-side tools and tests.

    ``take(timeout)`` blocks in a WaitSet until data arrives (or the timeout passes) and
    removes what it returns; ``read()`` returns what the reader holds without removing it
    (with keep-last-1 topics: the latest sample of every instance).
    """

    def __init__(self, bridge: DdsBridge, spec: TopicSpec, *, depth: int | None = None) -> None:
        self.spec = spec
        self.converter = converter_for(spec.type)
        qos = topic_qos(spec.kind, bridge.qos_settings)
        if depth is not None:
            qos = Qos(Policy.History.KeepLast(depth), base=qos)
        topic = bridge._topic(spec.name)
        self._matches = match_listener()
        self._reader: DataReader[Any] = DataReader(bridge._subscriber, topic, qos=qos,
                                                   listener=self._matches)
        self._condition = ReadCondition(self._reader, _ANY_SAMPLE)
        self._waitset = WaitSet(bridge._participant)
        self._waitset.attach(self._condition)
        self._closed = False

    def matched_writers(self) -> int:
        """How many writers (local or remote) currently match this reader: a reader of a
        volatile topic waits for its writer before that one writes."""
        return len(matched_publications(self._reader, self._matches))

    def wait(self, timeout: float) -> bool:
        """Block up to ``timeout`` seconds for a sample; True if one is there."""
        if self._condition.is_triggered():
            return True
        return bool(self._waitset.wait(duration(seconds=max(timeout, 0.0))))

    def take(self, timeout: float = 0.0, max_samples: int = _BATCH) -> list[dict[str, Any]]:
        """Up to ``max_samples`` sample dicts, waiting up to ``timeout`` s for the first."""
        if timeout > 0:
            self.wait(timeout)
        return self._plain(self._reader.take(N=max_samples, condition=self._condition))

    def read(self, max_samples: int = _BATCH) -> list[dict[str, Any]]:
        """Up to ``max_samples`` sample dicts still held by the reader, not removing them."""
        return self._plain(self._reader.read(N=max_samples))

    def collect(self, count: int, timeout: float) -> list[dict[str, Any]]:
        """Take until ``count`` samples arrived or ``timeout`` s passed; return them all."""
        deadline = time.monotonic() + timeout
        out: list[dict[str, Any]] = []
        while len(out) < count:
            left = deadline - time.monotonic()
            if left <= 0:
                break
            out += self.take(timeout=left)
        return out

    def _plain(self, samples: list[Any]) -> list[dict[str, Any]]:
        return [self.converter.to_dict(s) for s in samples if s.sample_info.valid_data]

    def instance_states(self) -> dict[tuple[Any, ...], str]:
        """Key tuple -> ``"alive"``, ``"disposed"`` or ``"no_writers"`` for held instances."""
        keys = key_members(self.spec.type)
        states = {
            InstanceState.Alive: "alive",
            InstanceState.NotAliveDisposed: "disposed",
            InstanceState.NotAliveNoWriters: "no_writers",
        }
        out = {}
        samples = self._reader.read(N=_BATCH)
        # the 0.10.2 binding's invalid samples (a dispose, no writers) carry the key only
        # serialised: find it from a valid sample of the same instance
        key_of = {s.sample_info.instance_handle: tuple(getattr(s, k) for k in keys)
                  for s in samples if s.sample_info.valid_data}
        for sample in samples:
            info = sample.sample_info
            if info.valid_data:
                key = key_of[info.instance_handle]
            elif hasattr(sample, "key_sample"):
                key = tuple(getattr(sample.key_sample, k) for k in keys)
            elif info.instance_handle in key_of:
                key = key_of[info.instance_handle]
            else:
                continue
            out[key] = states.get(info.instance_state, "unknown")
        return out

    def close(self) -> None:
        """Delete the reader. Idempotent."""
        if self._closed:
            return
        self._closed = True
        for entity in (self._waitset, self._condition, self._reader):
            _delete(entity)


def _delete(entity: Any) -> None:
    """Delete a Cyclone entity now rather than at garbage collection (idempotent)."""
    entity.__del__()
