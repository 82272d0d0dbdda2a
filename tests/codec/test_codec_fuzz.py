"""Bytes from a radio never crash the decoder: only DecodeError escapes ``decode_body``.

For every message of the default catalogue and of the test definitions, deterministic
random bodies, every prefix of a valid body, single-byte corruptions and an appended byte
are decoded. Each attempt must either give a dict or raise DecodeError naming the
message code and an offset inside the body, and the compiled path must reach exactly the
same result as the reference walker.
"""

from __future__ import annotations

import random
from typing import Any

import pytest
from codec_defs import ALL, catalogue_defs, ident
from strategies import random_fields

from edge_vis.codec import reference
from edge_vis.codec.bodies import decode_body, encode_body
from edge_vis.codec.types import MessageDef
from edge_vis.errors import DecodeError

RANDOM_BODIES = 40
FLIPS = 16
MAX_PREFIXES = 48


def outcome(fn: Any, defn: MessageDef, body: bytes) -> tuple[str, str]:
    """``("ok", repr(value))`` or ``("error", message)``; anything else propagates."""
    try:
        return "ok", repr(fn(defn, body))
    except DecodeError as exc:
        assert exc.code == defn.code, f"{exc} does not name 0x{defn.code:04X}"
        assert exc.offset is not None and 0 <= exc.offset <= len(body), exc
        return "error", str(exc)


def inputs_for(defn: MessageDef) -> list[bytes]:
    rng = random.Random(defn.code * 7919 + len(defn.name))
    bodies = [rng.randbytes(rng.randint(0, 48)) for _ in range(RANDOM_BODIES)]
    bodies += [b"", b"\xff" * 64]
    valid = encode_body(defn, random_fields(defn, rng, all_optional=True))
    bodies += [valid[:n] for n in range(min(len(valid), MAX_PREFIXES))]
    for _ in range(FLIPS if valid else 0):
        pos = rng.randrange(len(valid))
        flipped = bytes([valid[pos] ^ (1 << rng.randrange(8))])
        bodies.append(valid[:pos] + flipped + valid[pos + 1 :])
    bodies.append(valid + b"\x00")
    return bodies


@pytest.mark.parametrize("defn", [*ALL, *catalogue_defs()], ids=ident)
def test_only_decode_errors_escape(defn: MessageDef) -> None:
    for body in inputs_for(defn):
        fast = outcome(decode_body, defn, body)
        slow = outcome(reference.decode_body, defn, body)
        assert fast == slow, body.hex()
