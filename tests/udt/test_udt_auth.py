"""Authenticated bulk transfers: per-vehicle pre-shared keys, HMAC over manifest + challenge.

The sans-I/O tests drive a sender and a receiver connection against each other (and an
attacker replaying recorded bytes); the socket tests run real UDT on loopback through
``ImageService`` and ``send_image``: the right key delivers, a wrong or missing key is
refused with UNAUTHENTICATED, and nothing is stored under the vehicle's name.
"""

from __future__ import annotations

import stat
from pathlib import Path

import pytest

from edge_vis.errors import ConfigError
from links.udt.keys import load_keys, parse_keys
from links.udt.protocol import (
    FrameType,
    ManifestReceived,
    ManifestRejected,
    Reason,
    ReceiverConnection,
    SenderConnection,
    State,
    auth_tag,
    encode_frame,
    transfer_id_for,
)
from links.udt.protocol import Manifest as _Manifest

KEY = bytes(range(32))
OTHER = bytes(range(1, 33))


def manifest(vehicle: str = "uuv1", content: bytes = b"image") -> _Manifest:
    import hashlib

    digest = hashlib.sha256(content).hexdigest()
    return _Manifest(transfer_id_for(vehicle, "img.png", digest), vehicle, "img.png",
                     len(content), digest, "png", 1.7e9)


def exchange(sender: SenderConnection, receiver: ReceiverConnection,
             rounds: int = 4) -> list[object]:
    """Carry bytes both ways until quiet; return the receiver's events."""
    events: list[object] = []
    for _ in range(rounds):
        out = sender.data_to_send()
        if out:
            events += receiver.receive_data(out, 1.0)
        back = receiver.data_to_send()
        if back:
            events += sender.receive_data(back, 1.0)
    return events


def test_right_key_passes_and_the_challenge_is_fresh_each_time() -> None:
    nonces = iter([b"\x01" * 32, b"\x02" * 32])
    receiver = ReceiverConnection(keys={"uuv1": KEY}, nonce=lambda: next(nonces))
    sender = SenderConnection(keys={"uuv1": KEY})
    sender.send_manifest(manifest(), 0.0)
    events = exchange(sender, receiver)
    assert [type(e) for e in events] == [ManifestReceived]
    assert receiver.state is State.DECIDING
    receiver.refuse(Reason.BUSY, "later")  # the next manifest gets a new challenge
    exchange(sender, receiver)
    sender.send_manifest(manifest(), 0.0)
    assert [type(e) for e in exchange(sender, receiver)] == [ManifestReceived]


def test_wrong_key_is_refused_as_unauthenticated() -> None:
    receiver = ReceiverConnection(keys={"uuv1": KEY})
    sender = SenderConnection(keys={"uuv1": OTHER})
    sender.send_manifest(manifest(), 0.0)
    events = [e for e in exchange(sender, receiver) if isinstance(e, ManifestRejected)]
    assert events == [ManifestRejected(
        Reason.UNAUTHENTICATED, "authentication failed for vehicle 'uuv1': wrong key")]
    assert receiver.manifest is None and receiver.state is State.AWAIT_MANIFEST
    assert sender.state is State.IDLE  # the REFUSE came back


def test_unknown_vehicle_is_refused_without_a_challenge() -> None:
    receiver = ReceiverConnection(keys={"uuv1": KEY})
    sender = SenderConnection(keys={"intruder": KEY})
    sender.send_manifest(manifest("intruder"), 0.0)
    events = receiver.receive_data(sender.data_to_send(), 1.0)
    assert events == [ManifestRejected(Reason.UNAUTHENTICATED,
                                       "no key for vehicle 'intruder': not accepted here")]


def test_sender_without_a_key_fails_clearly() -> None:
    receiver = ReceiverConnection(keys={"uuv1": KEY})
    sender = SenderConnection()
    sender.send_manifest(manifest(), 0.0)
    receiver.receive_data(sender.data_to_send(), 1.0)
    events = sender.receive_data(receiver.data_to_send(), 1.0)
    assert sender.state is State.CLOSED
    assert events[0].code is Reason.UNAUTHENTICATED  # type: ignore[attr-defined]
    assert "no key for vehicle 'uuv1'" in events[0].reason  # type: ignore[attr-defined]


def test_replayed_manifest_and_tag_are_refused() -> None:
    """An attacker who recorded a genuine MANIFEST + AUTH cannot replay them."""
    receiver = ReceiverConnection(keys={"uuv1": KEY})
    sender = SenderConnection(keys={"uuv1": KEY})
    sender.send_manifest(manifest(), 0.0)
    recorded = sender.data_to_send()
    receiver.receive_data(recorded, 1.0)
    sender.receive_data(receiver.data_to_send(), 1.0)
    recorded_auth = sender.data_to_send()
    assert [type(e) for e in receiver.receive_data(recorded_auth, 1.0)] == [ManifestReceived]

    # a new connection: same bytes, new challenge -> refused
    fresh = ReceiverConnection(keys={"uuv1": KEY})
    fresh.receive_data(recorded, 2.0)
    events = fresh.receive_data(recorded_auth, 2.0)
    assert [e.code for e in events] == [Reason.UNAUTHENTICATED]  # type: ignore[attr-defined]
    # and the same connection does not take the old answer twice
    receiver.refuse(Reason.BUSY, "again")
    receiver.data_to_send()
    receiver.receive_data(recorded, 3.0)
    events = receiver.receive_data(recorded_auth, 3.0)
    assert [e.code for e in events] == [Reason.UNAUTHENTICATED]  # type: ignore[attr-defined]


def test_data_before_authentication_breaks_the_protocol() -> None:
    receiver = ReceiverConnection(keys={"uuv1": KEY})
    sender = SenderConnection(keys={"uuv1": KEY})
    sender.send_manifest(manifest(), 0.0)
    receiver.receive_data(sender.data_to_send(), 1.0)
    events = receiver.receive_data(encode_frame(FrameType.DATA, b"image"), 1.0)
    assert receiver.state is State.CLOSED
    assert events[-1].code is Reason.UNEXPECTED_FRAME  # type: ignore[attr-defined]


def test_tag_covers_the_manifest_bytes() -> None:
    a = auth_tag(KEY, b"\x00" * 32, manifest().to_json())
    b = auth_tag(KEY, b"\x00" * 32, manifest(content=b"other").to_json())
    assert a != b and len(a) == 32


def test_receiver_without_keys_does_not_challenge() -> None:
    receiver = ReceiverConnection()
    sender = SenderConnection()
    sender.send_manifest(manifest(), 0.0)
    assert [type(e) for e in exchange(sender, receiver)] == [ManifestReceived]


# -- the key file ---------------------------------------------------------------------------


def test_key_file_is_validated(tmp_path: Path) -> None:
    path = tmp_path / "keys.toml"
    path.write_text(f'[keys]\nuuv1 = "{KEY.hex()}"\n')
    path.chmod(0o600)
    assert load_keys(path) == {"uuv1": KEY}
    with pytest.raises(ConfigError) as err:
        parse_keys({"keys": {"a": "abc", "b": "00" * 8, "c": 5}}, "k.toml")
    assert err.value.problems == [
        ("k.toml", "keys.a", "expected the key as an even number of hex digits"),
        ("k.toml", "keys.b", "key of 8 bytes is too short (at least 16)"),
        ("k.toml", "keys.c", "expected the key as an even number of hex digits"),
    ]


def test_readable_key_file_is_warned_about(tmp_path: Path, caplog) -> None:
    path = tmp_path / "keys.toml"
    path.write_text(f'[keys]\nuuv1 = "{KEY.hex()}"\n')
    path.chmod(0o644)
    assert path.stat().st_mode & stat.S_IROTH
    load_keys(path)
    assert "readable by group or others" in caplog.text


# -- real UDT sockets -------------------------------------------------------------------------


@pytest.mark.udt
def test_only_the_key_holder_delivers_over_udt(tmp_path: Path, make_file) -> None:
    pytest.importorskip("udt4py")
    from links.udt import UdtBulkChannel

    path, content = make_file(200_000, "atr-1.png")
    fast = UdtBulkChannel.Backoff(initial=0.02, maximum=0.1, jitter=0.0)
    with UdtBulkChannel.ImageService(tmp_path / "relay", keys={"uuv1": KEY}) as relay:
        wrong = UdtBulkChannel.send_image(path, relay.address, vehicle_id="uuv1",
                                   keys={"uuv1": OTHER}, backoff=fast, give_up_after=5)
        assert not wrong.ok and wrong.code is Reason.UNAUTHENTICATED
        assert "wrong key" in wrong.reason
        missing = UdtBulkChannel.send_image(path, relay.address, vehicle_id="uuv1", backoff=fast,
                                     give_up_after=5)
        assert not missing.ok and missing.code is Reason.UNAUTHENTICATED
        stranger = UdtBulkChannel.send_image(path, relay.address, vehicle_id="uuv9",
                                      keys={"uuv9": KEY}, backoff=fast, give_up_after=5)
        assert not stranger.ok and stranger.code is Reason.UNAUTHENTICATED
        assert not (tmp_path / "relay" / "uuv1").exists()
        assert relay.receiver.counters["unauthenticated"] >= 2
        good = UdtBulkChannel.send_image(path, relay.address, vehicle_id="uuv1",
                                  keys={"uuv1": KEY}, backoff=fast, give_up_after=5)
        assert good.ok, good.reason
        assert (tmp_path / "relay" / "uuv1" / "atr-1.png").read_bytes() == content


def test_send_image_needs_a_key_for_its_vehicle(tmp_path: Path, capsys) -> None:
    from edge_vis.cli import main

    keys = tmp_path / "keys.toml"
    keys.write_text(f'[keys]\nuuv1 = "{KEY.hex()}"\n')
    keys.chmod(0o600)
    image = tmp_path / "a.png"
    image.write_bytes(b"png")
    code = main(["send-image", str(image), "--to", "127.0.0.1:9", "--vehicle", "uuv2",
                 "--keys", str(keys)])
    assert code == 2
    assert f"{keys}: no key for vehicle 'uuv2'" in capsys.readouterr().err
