"""The codec engine: encode and decode message bodies from their declarative definitions.

No I/O. Public entry points:

* :func:`decode_body` / :func:`encode_body` — a whole message body (the bytes after the
  2-byte message code) to and from a ``dict`` as described in :mod:`edge_vis.codec.types`;
* :func:`compile_message` — the :class:`MessageCodec` behind those two, for callers that
  keep a reference (the catalogue does);
* :func:`compile_type` — a :class:`TypeCodec` for any single field type:
  ``decode(buf, offset) -> (value, new_offset)`` and ``encode(value, out: bytearray)``.

Each definition is compiled on first use into specialised Python functions (see
:mod:`edge_vis.codec.compiler`) and cached. When a compiled function rejects its input the
engine replays it through the reference walker (:mod:`edge_vis.codec.reference`), which
raises the error with the message code, the field path (``elements[3].latitude``) and, for
decoding, the byte offset counted from the first byte of the body. Whatever bytes arrive,
decoding raises nothing but :class:`~edge_vis.errors.DecodeError`; bad values raise
:class:`~edge_vis.errors.EncodeError`; a broken *definition* raises ``ValueError`` when it
is compiled. The rules beyond the type table of :mod:`edge_vis.codec.types` (presence
bits without a field, absurd list counts, the scaled range, ``None`` values, ...) are
listed in :mod:`edge_vis.codec.reference`; the scaling convention is
:func:`~edge_vis.codec.layout.scaling`.
"""

from __future__ import annotations

import logging
from typing import Any

from edge_vis.codec import reference
from edge_vis.codec.compiler import Compiler
from edge_vis.codec.layout import check_message, check_type, scaling
from edge_vis.codec.types import FieldType, MessageDef
from edge_vis.errors import DecodeError

__all__ = [
    "MessageCodec",
    "TypeCodec",
    "compile_message",
    "compile_type",
    "decode_body",
    "encode_body",
    "scaling",
]

log = logging.getLogger(__name__)


class MessageCodec:
    """Compiled encoder and decoder of one message body.

    ``decode(body: bytes) -> dict`` raises DecodeError (with ``code``) on any bad input,
    including trailing bytes; ``encode(fields: dict) -> bytes`` raises EncodeError.
    ``fallbacks`` counts inputs the compiled path handed to the reference walker.
    """

    def __init__(self, defn: MessageDef) -> None:
        problems = check_message(defn)
        if problems:
            raise ValueError(
                f"invalid definition of {defn.name} (0x{defn.code:04X}): " + "; ".join(problems)
            )
        self.definition = defn
        self.fallbacks = 0
        self.compiler = Compiler(f"{defn.name}")
        self.decode = self.compiler.top_decoder(defn.body, self._slow_decode, whole=True)
        self.encode = self.compiler.top_encoder(defn.body, self._slow_encode, whole=True)

    def _slow_decode(self, body: bytes) -> dict[str, Any]:
        self.fallbacks += 1
        value = reference.decode_body(self.definition, body)
        log.debug("0x%04X decoded by the reference walker", self.definition.code)
        return value

    def _slow_encode(self, fields: Any) -> bytes:
        self.fallbacks += 1
        data = reference.encode_body(self.definition, fields)
        log.debug("0x%04X encoded by the reference walker", self.definition.code)
        return data

    def __repr__(self) -> str:
        return f"<MessageCodec {self.definition.name} 0x{self.definition.code:04X}>"


class TypeCodec:
    """Compiled codec of one field type.

    ``decode(buf, offset) -> (value, new_offset)`` raises DecodeError (path relative to
    the type, absolute offset in ``buf``); ``encode(value, out)`` appends to the bytearray
    ``out`` or raises EncodeError leaving ``out`` as it was.
    """

    def __init__(self, ft: FieldType) -> None:
        problems = check_type(ft)
        if problems:
            raise ValueError("invalid field type: " + "; ".join(problems))
        self.type = ft
        self.fallbacks = 0
        self.compiler = Compiler(type(ft).__name__)
        self.decode = self.compiler.top_decoder(ft, self._slow_decode, whole=False)
        self.encode = self.compiler.top_encoder(ft, self._slow_encode, whole=False)

    def _slow_decode(self, buf: bytes, pos: int) -> tuple[Any, int]:
        self.fallbacks += 1
        if pos < 0 or pos > len(buf):
            raise DecodeError(f"offset {pos} outside a buffer of {len(buf)} bytes", offset=pos)
        return reference.decode_type(self.type, buf, pos)

    def _slow_encode(self, value: Any, out: bytearray) -> None:
        self.fallbacks += 1
        encoded = bytearray()
        reference.encode_type(self.type, value, encoded)
        out += encoded


_messages: dict[int, MessageCodec] = {}
_types: dict[int, TypeCodec] = {}


def compile_message(defn: MessageDef) -> MessageCodec:
    """The cached :class:`MessageCodec` of ``defn`` (keyed by identity)."""
    codec = _messages.get(id(defn))
    if codec is None or codec.definition is not defn:
        codec = _messages[id(defn)] = MessageCodec(defn)
    return codec


def compile_type(ft: FieldType) -> TypeCodec:
    """The cached :class:`TypeCodec` of ``ft`` (keyed by identity)."""
    codec = _types.get(id(ft))
    if codec is None or codec.type is not ft:
        codec = _types[id(ft)] = TypeCodec(ft)
    return codec


def decode_body(defn: MessageDef, body: bytes) -> dict[str, Any]:
    """Decode a message body (the bytes after the 2-byte code) into a dict.

    Raises DecodeError naming ``defn.code``, the field path and the body offset; bytes left
    over after the last field are an error too.
    """
    codec = _messages.get(id(defn))
    if codec is None or codec.definition is not defn:
        codec = compile_message(defn)
    return codec.decode(body)


def encode_body(defn: MessageDef, fields: dict[str, Any]) -> bytes:
    """Encode a dict into a message body (without the 2-byte code).

    The presence vector follows from which optional keys are present. Raises EncodeError
    naming ``defn.code`` and the field path for unknown or missing keys and for values the
    field cannot carry.
    """
    codec = _messages.get(id(defn))
    if codec is None or codec.definition is not defn:
        codec = compile_message(defn)
    return codec.encode(fields)
