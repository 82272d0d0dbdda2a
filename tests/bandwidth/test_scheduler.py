"""The link scheduler (the router's per-link queues with a link profile) on a fake clock."""

from __future__ import annotations

from edge_vis.bandwidth.linkspec import LinkSpec
from edge_vis.jaus.address import JausAddress
from edge_vis.jaus.transport import DataFlags, Packet
from edge_vis.routing.router import Router, SendPackets
from edge_vis.routing.traffic import QueueDrop, latest_wins_key, priority_for

RELAY = JausAddress(200, 1, 1)
UGV = JausAddress(101, 1, 1)
OTHER = JausAddress(102, 1, 1)
SPEC = LinkSpec(bit_rate=19200, bits_per_byte=10, budget=0.8, mtu=256, overhead=18)
TELEMETRY = SPEC.priority_of("telemetry")
COMMAND = SPEC.priority_of("command")


def router() -> Router:
    r = Router([RELAY])
    r.add_link("radio", mtu=SPEC.mtu, bandwidth_bps=SPEC.budget_bps, overhead=SPEC.overhead,
               latest_wins=True)
    r.add_route(JausAddress(0xFFFF, 0xFF, 0xFF), "radio", "radio")
    return r


def query(code: int, dest: JausAddress = UGV, body: bytes = b"\xff\x01",
          priority: int = TELEMETRY) -> Packet:
    return Packet(dest, RELAY, code.to_bytes(2, "little") + body, priority=priority)


def sent(actions: list) -> list[Packet]:
    return [p for a in actions if isinstance(a, SendPackets) for p in a.packets]


def fill(r: Router, now: float) -> None:
    """Spend the link's burst so later packets queue."""
    for i in range(8):
        r.send(query(0x2B00 + i, body=bytes(200)), now)


def test_commands_overtake_queued_telemetry() -> None:
    r = router()
    fill(r, 0.0)
    r.send(query(0x2402), 0.0)  # QueryGlobalPose, telemetry
    r.send(query(0x0405, body=b"\x01\x00\x10", priority=COMMAND), 0.0)  # SetWrenchEffort
    out = sent(r.on_timer(r.next_deadline() or 0.0))
    assert out and out[0].message_code == 0x0405


def test_latest_wins_for_telemetry_never_for_commands() -> None:
    r = router()
    fill(r, 0.0)
    for _ in range(5):
        r.send(query(0x2402), 0.0)             # the same poll five times: one waits
        r.send(query(0x2402, dest=OTHER), 0.0)  # another vehicle's is its own
        r.send(query(0x0405, body=b"\x01\x00\x10", priority=COMMAND), 0.0)
    now, out = 0.0, []
    while r.stats().links["radio"].depth:
        now = max(now, r.next_deadline() or now)
        out += sent(r.on_timer(now))
    codes = [(p.message_code, p.destination) for p in out]
    assert codes.count((0x2402, UGV)) == 1 and codes.count((0x2402, OTHER)) == 1
    assert codes.count((0x0405, UGV)) == 5  # commands are never superseded or dropped
    drops = r.stats().links["radio"].drops
    assert drops == {QueueDrop("superseded", TELEMETRY): 8}


def test_paced_at_the_budget() -> None:
    r = router()
    total = 0
    now = 0.0
    for i in range(400):  # offered: 400 x 64 B in 2 s = 12.8 kB/s, far above the budget
        now = i * 0.005
        for p in sent(r.on_timer(now) + r.send(query(0x2B00, body=bytes(30) + bytes([i % 256])),
                                                now)):
            total += len(p.payload) + 14 + SPEC.overhead
    # everything that left in 2 s: budget x 2 s plus the 50 ms burst at most
    assert total <= SPEC.budget_bytes * 2.0 + SPEC.budget_bytes * 0.05 + 100
    assert total >= SPEC.budget_bytes * 2.0 * 0.9


def test_a_command_waits_behind_at_most_one_fragment() -> None:
    r = router()
    fill(r, 0.0)
    big = Packet(UGV, RELAY, (0x4402).to_bytes(2, "little") + bytes(2000), priority=0)
    r.send(big, 0.0)  # 8 fragments of at most 256 bytes, bulk priority
    now, out = 0.0, []
    for _ in range(200):
        now = r.next_deadline() or now
        got = sent(r.on_timer(now))
        out += got
        if any(p.data_flags != DataFlags.SINGLE for p in got):
            break  # the first fragment is on the air: now the operator sends a command
    r.send(query(0x0405, body=b"\x01\x00\x10", priority=COMMAND), now)
    rest = []
    while r.stats().links["radio"].depth:
        now = r.next_deadline() or now
        rest += sent(r.on_timer(now))
    assert all(len(p.payload) <= SPEC.mtu for p in out + rest)
    first_command = next(i for i, p in enumerate(rest) if p.message_code == 0x0405)
    assert first_command == 0, [p.data_flags for p in rest[:3]]
    assert sum(1 for p in out + rest if p.data_flags != DataFlags.SINGLE) >= 8


def test_latest_wins_keys() -> None:
    event = Packet(RELAY, UGV, b"\xf1\x41\x01\x07\x04\x00\x00\x00\x02\x44" + bytes(4))
    assert latest_wins_key(event) == (UGV.id, RELAY.id, 0x41F1, 0x4402)
    assert latest_wins_key(query(0x0405)) is None          # commands: never
    assert latest_wins_key(query(0x2402)) != latest_wins_key(query(0x2402, body=b"\x01\x00"))
    assert priority_for("command", 0, SPEC.priorities) == 3
    assert priority_for("telemetry", 3, SPEC.priorities) == 3  # safety stays safety
