"""The store-and-forward spool on a real disk: journal, restart, quota, verification."""

from __future__ import annotations

import hashlib
import os
from dataclasses import replace
from pathlib import Path

import pytest

from links.udt.protocol import Manifest, Reason, transfer_id_for
from links.udt.spool import EntryState, Spool, SpoolRefusal


def manifest_for(content: bytes, name: str = "img.png", vehicle: str = "uuv1") -> Manifest:
    sha = hashlib.sha256(content).hexdigest()
    return Manifest(transfer_id_for(vehicle, name, sha), vehicle, name, len(content), sha,
                    "png", 1.7e9)


def files_under(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file()}


def test_partial_data_survives_a_restart_at_the_durable_offset(tmp_path: Path):
    content = os.urandom(300_000)
    m = manifest_for(content)
    spool = Spool(tmp_path / "s", sync_bytes=100_000, sync_interval=3600.0)
    assert spool.begin(m) == 0
    spool.write(m.transfer_id, 0, content[:150_000])  # one sync at 150 000 bytes
    spool.write(m.transfer_id, 150_000, content[150_000:180_000])  # not yet durable
    # Simulate a crash: no release(), no close(); a new process opens the same spool.
    spool._journal.close()
    again = Spool(tmp_path / "s")
    assert again.begin(m) == 150_000
    again.write(m.transfer_id, 150_000, content[150_000:])
    path = again.complete(m.transfer_id)
    again.release(m.transfer_id)
    assert path.read_bytes() == content


def test_release_makes_everything_received_durable(tmp_path: Path):
    content = os.urandom(50_000)
    m = manifest_for(content)
    spool = Spool(tmp_path / "s")
    spool.begin(m)
    spool.write(m.transfer_id, 0, content[:12_345])
    spool.release(m.transfer_id)
    spool.close()
    assert Spool(tmp_path / "s").begin(m) == 12_345


def test_torn_journal_line_and_longer_file_are_cut_back(tmp_path: Path):
    content = os.urandom(10_000)
    m = manifest_for(content)
    spool = Spool(tmp_path / "s")
    spool.begin(m)
    spool.write(m.transfer_id, 0, content[:4000])
    spool.release(m.transfer_id)
    spool.close()
    with open(tmp_path / "s" / "journal.log", "a") as fh:
        fh.write('{"op":"durable","id":"')  # power lost mid-append
    with open(tmp_path / "s" / "partial" / f"{m.transfer_id}.part", "ab") as fh:
        fh.write(b"torn tail never recorded as durable")
    again = Spool(tmp_path / "s")
    assert again.counters["torn_journal_lines"] == 1
    assert again.begin(m) == 4000
    assert (tmp_path / "s" / "partial" / f"{m.transfer_id}.part").stat().st_size == 4000


def test_hash_mismatch_discards_the_data_and_says_why(tmp_path: Path):
    content = os.urandom(5000)
    m = manifest_for(content)
    spool = Spool(tmp_path / "s")
    spool.begin(m)
    spool.write(m.transfer_id, 0, b"\x00" * 5000)  # right size, wrong bytes
    with pytest.raises(SpoolRefusal, match="SHA-256 mismatch") as info:
        spool.complete(m.transfer_id)
    assert info.value.code is Reason.HASH_MISMATCH
    spool.release(m.transfer_id)
    assert spool.entry(m.transfer_id) is None
    assert spool.begin(m) == 0  # a retry starts clean


def test_quota_refuses_new_transfers_and_never_deletes_unsent_data(tmp_path: Path):
    spool = Spool(tmp_path / "s", quota_bytes=100_000, forward_targets=("ops:9000",))
    first = os.urandom(70_000)
    m1 = manifest_for(first, "one.png")
    spool.begin(m1)
    spool.write(m1.transfer_id, 0, first)
    spool.complete(m1.transfer_id)
    spool.release(m1.transfer_id)
    m2 = manifest_for(os.urandom(40_000), "two.png")
    with pytest.raises(SpoolRefusal, match=r"spool quota full: two.png needs 39.1 KiB, "
                                           r"29.3 KiB free of 97.7 KiB") as info:
        spool.begin(m2)
    assert info.value.code is Reason.QUOTA
    assert (tmp_path / "s" / "ready" / m1.transfer_id).read_bytes() == first  # kept
    assert [m.name for m, _ in spool.outbox("ops:9000")] == ["one.png"]
    # Once forwarded, the space is free again.
    spool.mark_forwarded(m1.transfer_id, "ops:9000")
    assert not (tmp_path / "s" / "ready" / m1.transfer_id).exists()
    assert spool.begin(m2) == 0


def test_oversized_transfer_is_refused_up_front(tmp_path: Path):
    spool = Spool(tmp_path / "s", quota_bytes=1000)
    m = manifest_for(os.urandom(1001))
    with pytest.raises(SpoolRefusal) as info:
        spool.begin(m)
    assert info.value.code is Reason.QUOTA
    assert files_under(tmp_path / "s") == {"journal.log"}


def test_same_transfer_on_two_connections_is_busy(tmp_path: Path):
    spool = Spool(tmp_path / "s")
    m = manifest_for(b"abc")
    spool.begin(m)
    with pytest.raises(SpoolRefusal) as info:
        spool.begin(m)
    assert info.value.code is Reason.BUSY
    spool.release(m.transfer_id)
    assert spool.begin(m) == 0


def test_conflicting_manifest_for_a_known_id_is_refused(tmp_path: Path):
    spool = Spool(tmp_path / "s")
    m = manifest_for(b"abc")
    spool.begin(m)
    spool.release(m.transfer_id)
    liar = Manifest(m.transfer_id, m.vehicle_id, m.name, 4, m.sha256, "png", 1.7e9)
    with pytest.raises(SpoolRefusal, match="different manifest") as info:
        spool.begin(liar)
    assert info.value.code is Reason.BAD_MANIFEST


def test_delivery_and_idempotent_resend_after_done(tmp_path: Path):
    content = b"an image"
    m = manifest_for(content, "sonar.png", "uuv7")
    spool = Spool(tmp_path / "s", deliver_dir=tmp_path / "out")
    spool.begin(m)
    spool.write(m.transfer_id, 0, content)
    spool.complete(m.transfer_id)
    spool.release(m.transfer_id)
    assert (tmp_path / "out" / "uuv7" / "sonar.png").read_bytes() == content
    assert spool.entry(m.transfer_id).state is EntryState.DONE
    spool.close()
    # A sender that never saw the receipt sends the manifest again after a restart:
    # the spool knows it is done and offers the full size, so nothing is re-sent.
    again = Spool(tmp_path / "s", deliver_dir=tmp_path / "out")
    assert again.begin(m) == len(content)
    assert files_under(tmp_path / "out") == {"uuv7/sonar.png"}


def test_name_clash_in_the_output_keeps_both_files(tmp_path: Path):
    spool = Spool(tmp_path / "s", deliver_dir=tmp_path / "out")
    for content in (b"first", b"second"):
        m = manifest_for(content, "same.png")
        spool.begin(m)
        spool.write(m.transfer_id, 0, content)
        spool.complete(m.transfer_id)
        spool.release(m.transfer_id)
    out = sorted((tmp_path / "out" / "uuv1").iterdir())
    assert len(out) == 2
    assert {p.read_bytes() for p in out} == {b"first", b"second"}


def test_outbox_survives_restart_until_forwarded(tmp_path: Path):
    content = os.urandom(1000)
    m = manifest_for(content)
    spool = Spool(tmp_path / "s", forward_targets=("a:1", "b:2"))
    spool.begin(m)
    spool.write(m.transfer_id, 0, content)
    spool.complete(m.transfer_id)
    spool.release(m.transfer_id)
    spool.mark_forwarded(m.transfer_id, "a:1")
    spool.close()
    again = Spool(tmp_path / "s", forward_targets=("a:1", "b:2"))
    assert list(again.outbox("a:1")) == []
    [(got, path)] = list(again.outbox("b:2"))
    assert got == m and path.read_bytes() == content


def test_lanes_write_their_segments_concurrently_and_resume_each(tmp_path: Path):
    content = os.urandom(1_000_000)
    m = manifest_for(content)
    lanes = [replace(m, segment=(i, 3)) for i in range(3)]
    spool = Spool(tmp_path / "s", sync_interval=3600.0)
    for lane in lanes:
        assert spool.begin(lane) == 0
    # Interleaved writes, as three connections deliver them.
    for step in range(0, 200_000, 50_000):
        for lane in lanes:
            a, _ = lane.span()
            spool.write(lane, step, content[a + step:a + step + 50_000])
    for lane in lanes:
        spool.release(lane)
    spool.close()
    again = Spool(tmp_path / "s")
    assert [again.begin(lane) for lane in lanes] == [200_000] * 3
    with pytest.raises(SpoolRefusal) as busy:
        again.begin(m)  # the whole file while lanes hold it
    assert busy.value.code is Reason.BUSY
    for lane in lanes:
        a, b = lane.span()
        spool_off = 200_000
        again.write(lane, spool_off, content[a + spool_off:b])
        again.release(lane)
    assert again.all_held(m.transfer_id)
    assert again.begin(m) == len(content)  # nothing left to send: verify
    assert again.complete(m).read_bytes() == content


def test_whole_file_after_partial_lanes_continues_from_the_contiguous_prefix(tmp_path: Path):
    content = os.urandom(600_000)
    m = manifest_for(content)
    first, second = (replace(m, segment=(i, 2)) for i in range(2))
    spool = Spool(tmp_path / "s")
    spool.begin(first)
    spool.write(first, 0, content[: first.length])  # lane 1 complete
    spool.release(first)
    spool.begin(second)
    spool.write(second, 0, content[first.length:first.length + 1000])  # lane 2 started
    spool.release(second)
    # The sender comes back without lanes: it sends from the contiguous prefix on.
    held = spool.begin(m)
    assert held == first.length + 1000
    spool.write(m.transfer_id, held, content[held:])
    assert spool.complete(m).read_bytes() == content


def test_a_different_lane_count_is_refused_clearly(tmp_path: Path):
    m = manifest_for(os.urandom(300_000))
    spool = Spool(tmp_path / "s")
    spool.begin(replace(m, segment=(0, 4)))
    with pytest.raises(SpoolRefusal, match="received in 4 lane"):
        spool.begin(replace(m, segment=(0, 2)))


def test_the_prefix_is_hashed_as_it_grows_so_the_verdict_reads_only_the_rest(tmp_path: Path):
    """Segments arrive out of order; each one made durable extends the hashed prefix as
    far as the file is held from its start, and the verdict still checks every byte."""
    content = os.urandom(800_000)
    m = manifest_for(content)
    lanes = [replace(m, segment=(i, 4)) for i in range(4)]
    spool = Spool(tmp_path / "s", sync_interval=3600.0)
    hashed = []
    for i in (1, 0, 3, 2):
        a, b = lanes[i].span()
        spool.begin(lanes[i])
        spool.write(lanes[i], 0, content[a:b])
        spool.release(lanes[i])
        hashed.append(spool.entry(m.transfer_id).hashed)
    assert hashed == [0, lanes[1].span()[1], lanes[1].span()[1], len(content)]
    assert spool.complete(m).read_bytes() == content


def test_a_corrupted_byte_hashed_on_the_way_is_refused_and_the_file_taken_again(
        tmp_path: Path):
    content = os.urandom(600_000)
    m = manifest_for(content)
    lanes = [replace(m, segment=(i, 3)) for i in range(3)]
    bad = bytearray(content)
    bad[1234] ^= 0x01  # one bit, in the first segment: hashed before the verdict
    spool = Spool(tmp_path / "s")
    for lane in lanes:
        a, b = lane.span()
        spool.begin(lane)
        spool.write(lane, 0, bytes(bad[a:b]))
        spool.release(lane)
    assert spool.entry(m.transfer_id).hashed == len(content)
    with pytest.raises(SpoolRefusal, match="SHA-256 mismatch") as info:
        spool.complete(m)
    assert info.value.code is Reason.HASH_MISMATCH
    assert spool.entry(m.transfer_id) is None
    for lane in lanes:  # taken again, from the start
        a, b = lane.span()
        assert spool.begin(lane) == 0
        spool.write(lane, 0, content[a:b])
        spool.release(lane)
    assert spool.complete(m).read_bytes() == content


def test_after_a_restart_the_verdict_hashes_the_whole_file_again(tmp_path: Path):
    """What was hashed on the way lives in memory only: a restarted spool reads every
    byte, so a file changed on disk while the relay was down is still refused."""
    content = os.urandom(400_000)
    m = manifest_for(content)
    lanes = [replace(m, segment=(i, 2)) for i in range(2)]
    spool = Spool(tmp_path / "s")
    a, b = lanes[0].span()
    spool.begin(lanes[0])
    spool.write(lanes[0], 0, content[a:b])
    spool.release(lanes[0])
    assert spool.entry(m.transfer_id).hashed == b
    spool.close()
    part = tmp_path / "s" / "partial" / f"{m.transfer_id}.part"
    data = bytearray(part.read_bytes())
    data[10] ^= 0xFF
    part.write_bytes(bytes(data))
    again = Spool(tmp_path / "s")
    a, b = lanes[1].span()
    assert again.begin(lanes[1]) == 0
    again.write(lanes[1], 0, content[a:b])
    again.release(lanes[1])
    with pytest.raises(SpoolRefusal, match="SHA-256 mismatch"):
        again.complete(m)
