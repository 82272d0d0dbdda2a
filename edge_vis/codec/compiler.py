"""Turns a type tree into specialised Python functions: the codec's fast path. No I/O.

Theory of operation
-------------------
Walking a definition field by field for every message costs a Python call, an
``isinstance`` chain and a ``struct`` call per field. Instead, each definition is compiled
once into Python source that is ``exec``-ed into a private namespace:

* consecutive fixed-size fields (integers, floats, scaled and enumerated integers, bit
  fields, fixed strings and bytes, and records of those) become **one** ``struct.Struct``
  and one ``unpack_from``/``pack`` call, with scaling (``raw * scale + bias`` and
  ``round((real - bias) / scale)``) written inline as literals;
* a record with a presence vector is compiled **per presence-vector value**, lazily, on
  first sight of that value; the specialised function has no branches at all. The decoder
  reads the vector with byte indexing and the specialised struct skips it as padding, so a
  full ReportGlobalPose is one ``unpack_from`` plus one dict display. After
  :data:`PV_CACHE_LIMIT` distinct values of one record (real peers use a handful), further
  values are handled by the reference walker instead, so line noise cannot make the codec
  generate code without bound;
* a list of fixed-size elements decodes with ``Struct.iter_unpack`` in a comprehension;
* variable-length parts (counted strings, bytes, embedded messages, lists of variable
  elements, variants) end the current struct run and continue with plain slicing.

The generated code checks only what it must for correctness (buffer bounds on slices,
list counts, tags, presence-vector bits, key counts, string lengths); everything else is
left to ``struct``, which rejects short buffers and integers out of range. Any failure
surfaces as one of :data:`DECODE_ERRORS` / :data:`ENCODE_ERRORS`, and the caller then runs
the same input through the reference walker (:mod:`edge_vis.codec.reference`), which
knows field paths and offsets and raises the precise error. The two paths take their
constants from :mod:`edge_vis.codec.layout`, and the tests check they agree.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

from edge_vis.codec import reference
from edge_vis.codec.layout import (
    fixed_size,
    min_size,
    optional_fields,
    scaling,
    subfield_mask,
    tag_values,
)
from edge_vis.codec.types import (
    BitField,
    Enum,
    FieldType,
    FixedBytes,
    FixedString,
    Float,
    Int,
    JausMessage,
    List,
    Record,
    Scaled,
    VarBytes,
    VarFormat,
    Variant,
    VarString,
)
from edge_vis.errors import DecodeError, EncodeError


class Reject(Exception):
    """Raised by generated code for input that the reference walker must diagnose."""


#: what a generated decoder may raise on bad input
DECODE_ERRORS = (
    struct.error, IndexError, KeyError, ValueError, TypeError, OverflowError, Reject,
    DecodeError,
)
#: what a generated encoder may raise on a bad value
ENCODE_ERRORS = (
    struct.error, IndexError, KeyError, ValueError, TypeError, OverflowError,
    AttributeError, Reject, EncodeError,
)

#: presence-vector values compiled per record; further values are walked by the reference
#: code, so noise cannot make the codec compile (and keep) code without bound
PV_CACHE_LIMIT = 64

Decoder = Callable[[bytes, int], tuple[Any, int]]
Encoder = Callable[[Any, bytearray], None]


class Compiler:
    """Generates and ``exec``-s the functions of one definition into one namespace."""

    def __init__(self, label: str) -> None:
        self.label = label
        self.ns: dict[str, Any] = {
            "Reject": Reject,
            "_BYTES": (bytes, bytearray),
            "_SEQ": (list, tuple),
        }
        self.sources: list[str] = []
        self._counter = 0
        self._structs: dict[str, str] = {}
        self._pv_dec: dict[int, tuple[str, str]] = {}
        self._pv_enc: dict[int, tuple[str, str]] = {}
        self._variant_dec: dict[int, str] = {}
        self._variant_enc: dict[int, str] = {}
        self._bitfields: dict[int, str] = {}
        self._keep: list[object] = []

    # -- namespace helpers ---------------------------------------------------------------

    def name(self, prefix: str) -> str:
        """A fresh identifier."""
        self._counter += 1
        return f"{prefix}{self._counter}"

    def const(self, obj: object, prefix: str = "K") -> str:
        """Bind ``obj`` in the namespace under a fresh name."""
        name = self.name(prefix)
        self.ns[name] = obj
        return name

    def struct(self, codes: list[str]) -> str:
        """Name of a cached ``struct.Struct`` for the concatenated little-endian codes."""
        fmt = "<" + "".join(codes)
        name = self._structs.get(fmt)
        if name is None:
            name = self._structs[fmt] = self.const(struct.Struct(fmt), "S")
        return name

    def define(self, lines: list[str], fname: str) -> Any:
        """Exec the source in ``lines`` and return the function ``fname`` it defines."""
        src = "\n".join(lines) + "\n"
        self.sources.append(src)
        exec(compile(src, f"<edge_vis codec {self.label}>", "exec"), self.ns)
        return self.ns[fname]

    # -- decoders ------------------------------------------------------------------------

    def top_decoder(self, ft: FieldType, slow: Callable[..., Any], whole: bool) -> Any:
        """The entry point: coerces the buffer, decodes, falls back to ``slow`` on error.

        ``whole``: the function takes ``(buf)``, decodes a whole body and rejects trailing
        bytes; otherwise it takes ``(buf, pos)`` and returns ``(value, pos)``.
        """
        fname = self.name("top")
        slow_name = self.const(slow, "SLOW")
        errors = self.const(DECODE_ERRORS, "ERR")
        args = "buf" if whole else "buf, pos"
        lines = [
            f"def {fname}({args}):",
            "    if buf.__class__ is not bytes:",
            "        buf = bytes(buf)",
        ]
        if whole:
            lines.append("    pos = 0")
        else:
            lines.append("    start = pos")
        lines.append("    try:")
        if not whole:
            lines += ["        if pos < 0:", "            raise Reject"]
        block = _DecBlock(self, lines, 2)
        expr = block.dec(ft)
        block.flush()
        if whole:
            block.emit(f"if {block.at()} == len(buf):")
            block.emit(f"    return {expr}")
        else:
            block.emit(f"return {expr}, {block.at()}")
        lines.append(f"    except {errors}:")
        lines.append("        pass")
        lines.append(f"    return {slow_name}({args if whole else 'buf, start'})")
        return self.define(lines, fname)

    def pv_record_decoder(self, rec: Record) -> tuple[str, str]:
        """Names of the per-value cache and of the miss handler of a presence-vector record."""
        key = id(rec)
        found = self._pv_dec.get(key)
        if found is not None:
            return found
        self._keep.append(rec)
        cache: dict[int, Decoder] = {}
        n_opt = len(optional_fields(rec))

        def walk(buf: bytes, pos: int) -> tuple[Any, int]:
            return reference.decode_type(rec, buf, pos)

        def miss(pv: int) -> Decoder:
            if pv >> n_opt:
                raise Reject
            if len(cache) >= PV_CACHE_LIMIT:
                return walk
            fn = cache[pv] = self._specialised_decoder(rec, pv)
            return fn

        names = (self.const(cache, "PVC"), self.const(miss, "PVM"))
        self._pv_dec[key] = names
        return names

    def _specialised_decoder(self, rec: Record, pv: int) -> Decoder:
        assert rec.pv is not None
        fname = self.name(f"dpv{pv:x}_")
        lines = [f"def {fname}(buf, pos):"]
        block = _DecBlock(self, lines, 1)
        block.pad(rec.pv.size)
        expr = block.record_fields(rec, pv)
        block.flush()
        block.emit(f"return {expr}, {block.at()}")
        return self.define(lines, fname)

    def variant_decoders(self, var: Variant) -> str:
        """Name of the tag -> alternative decoder table of a variant."""
        key = id(var)
        found = self._variant_dec.get(key)
        if found is not None:
            return found
        self._keep.append(var)
        table: dict[int, Decoder] = {}
        name = self._variant_dec[key] = self.const(table, "VD")
        for tag, alt in zip(tag_values(var), var.alternatives, strict=True):
            fname = self.name("dalt")
            lines = [f"def {fname}(buf, pos):"]
            block = _DecBlock(self, lines, 1)
            expr = block.dec(alt.type)
            block.flush()
            block.emit(f"return {{{alt.name!r}: {expr}}}, {block.at()}")
            table[tag] = self.define(lines, fname)
        return name

    # -- encoders ------------------------------------------------------------------------

    def top_encoder(self, ft: FieldType, slow: Callable[..., Any], whole: bool) -> Any:
        """The entry point: encodes, falls back to ``slow`` on error.

        ``whole``: the function takes ``(fields)`` and returns bytes; otherwise it takes
        ``(value, out)`` and appends to the bytearray ``out`` (restored on failure).
        """
        fname = self.name("tenc")
        slow_name = self.const(slow, "SLOW")
        errors = self.const(ENCODE_ERRORS, "ERR")
        if whole and isinstance(ft, Record) and ft.pv is not None:
            cache, miss = self.pv_record_encoder(ft, top=True)
            all_pv = (1 << len(optional_fields(ft))) - 1
            lines = [
                f"def {fname}(r):",
                "    try:",
                # every field present (usual for reports): skip the key tests; if a key is
                # unknown and another missing, the specialised function raises KeyError
                f"        if len(r) == {len(ft.fields)}:",
                f"            pv = {all_pv}",
                "        else:",
                "            " + f"pv = {_pv_expr(ft, 'r')}",
                f"        fn = {cache}.get(pv)",
                "        if fn is None:",
                f"            fn = {miss}(pv)",
                "        return fn(r)",
                f"    except {errors}:",
                "        pass",
                f"    return {slow_name}(r)",
            ]
            return self.define(lines, fname)
        if whole:
            lines = [f"def {fname}(r):", "    try:"]
            block = _EncBlock(self, lines, 2)
            block.enc(ft, "r")
            block.finish_bytes()
            lines += [f"    except {errors}:", "        pass", f"    return {slow_name}(r)"]
            return self.define(lines, fname)
        lines = [f"def {fname}(v, out):", "    mark = len(out)", "    try:"]
        block = _EncBlock(self, lines, 2)
        block.enc(ft, "v")
        block.flush()
        block.emit("return None")
        lines += [
            f"    except {errors}:",
            "        del out[mark:]",
            f"    return {slow_name}(v, out)",
        ]
        return self.define(lines, fname)

    def pv_record_encoder(self, rec: Record, top: bool = False) -> tuple[str, str]:
        """Names of the per-value cache and miss handler of a presence-vector record.

        With ``top`` the specialised functions take ``(fields)`` and return bytes;
        otherwise they take ``(fields, out)`` and append.
        """
        key = id(rec) * 2 + top
        found = self._pv_enc.get(key)
        if found is not None:
            return found
        self._keep.append(rec)
        cache: dict[int, Any] = {}

        def walk(r: Any, out: bytearray | None = None) -> bytes | None:
            data = bytearray()
            reference.encode_type(rec, r, data)
            if out is None:
                return bytes(data)
            out += data
            return None

        def miss(pv: int) -> Any:
            if len(cache) >= PV_CACHE_LIMIT:
                return walk
            fn = cache[pv] = self._specialised_encoder(rec, pv, top)
            return fn

        names = (self.const(cache, "EPC"), self.const(miss, "EPM"))
        self._pv_enc[key] = names
        return names

    def _specialised_encoder(self, rec: Record, pv: int, top: bool) -> Any:
        assert rec.pv is not None
        fname = self.name(f"epv{pv:x}_")
        lines = [f"def {fname}(r):" if top else f"def {fname}(r, out):"]
        block = _EncBlock(self, lines, 1)
        n_present = sum(1 for f in rec.fields if not f.optional) + bin(pv).count("1")
        block.emit(f"if len(r) != {n_present}:")
        block.emit("    raise Reject")
        block.add(rec.pv.struct_code, str(pv))
        block.record_fields(rec, "r", pv)
        if top:
            block.finish_bytes()
        else:
            block.flush()
        return self.define(lines, fname)

    def variant_encoders(self, var: Variant) -> str:
        """Name of the alternative name -> encoder table of a variant."""
        key = id(var)
        found = self._variant_enc.get(key)
        if found is not None:
            return found
        self._keep.append(var)
        table: dict[str, Encoder] = {}
        name = self._variant_enc[key] = self.const(table, "VE")
        for tag, alt in zip(tag_values(var), var.alternatives, strict=True):
            fname = self.name("ealt")
            lines = [f"def {fname}(v, out):"]
            block = _EncBlock(self, lines, 1)
            block.add(var.tag.struct_code, str(tag))
            block.enc(alt.type, "v")
            block.flush()
            lines.append("    return None")
            table[alt.name] = self.define(lines, fname)
        return name

    def bitfield_packer(self, bf: BitField) -> str:
        """Name of a generated function validating and packing a bit-field dict."""
        found = self._bitfields.get(id(bf))
        if found is not None:
            return found
        self._keep.append(bf)
        fname = self.name("bf")
        names = self.const(frozenset(s.name for s in bf.subfields), "BFN")
        lines = [f"def {fname}(v):", f"    if not v.keys() <= {names}:", "        raise Reject"]
        checks, parts = [], []
        for i, sub in enumerate(bf.subfields):
            var = f"x{i}"
            lines.append(f"    {var} = v.get({sub.name!r}, 0)")
            checks.append(f"0 <= {var} <= {subfield_mask(sub.lo, sub.hi)}")
            parts.append(f"{var} << {sub.lo}" if sub.lo else var)
        if checks:
            lines.append(f"    if not ({' and '.join(checks)}):")
            lines.append("        raise Reject")
        lines.append(f"    return {' | '.join(parts) if parts else '0'}")
        name = self._bitfields[id(bf)] = self.const(self.define(lines, fname), "BF")
        return name


def _pv_expr(rec: Record, var: str) -> str:
    """Expression computing the presence vector of the dict ``var``."""
    parts = []
    for bit, name in enumerate(optional_fields(rec)):
        test = f"({name!r} in {var})"
        parts.append(f"{test} << {bit}" if bit else test)
    return " | ".join(parts) if parts else "0"


class _Block:
    """Shared state of a stretch of generated statements at one indentation."""

    def __init__(self, comp: Compiler, lines: list[str], indent: int) -> None:
        self.c = comp
        self.lines = lines
        self.indent = indent

    def emit(self, line: str) -> None:
        self.lines.append("    " * self.indent + line)


class _DecBlock(_Block):
    """Decoding statements; fixed-size reads accumulate into one pending struct run.

    ``off`` is the static offset of the next unread byte relative to the local ``pos``;
    ``pos`` itself is only reassigned after a variable-length step.
    """

    def __init__(self, comp: Compiler, lines: list[str], indent: int) -> None:
        super().__init__(comp, lines, indent)
        self.codes: list[str] = []
        self.vars: list[str] = []
        self.run_at = 0
        self.off = 0

    def at(self) -> str:
        return f"pos + {self.off}" if self.off else "pos"

    def take(self, code: str, size: int) -> str:
        if not self.codes:
            self.run_at = self.off
        var = self.c.name("v")
        self.codes.append(code)
        self.vars.append(var)
        self.off += size
        return var

    def pad(self, size: int) -> None:
        if not self.codes:
            self.run_at = self.off
        self.codes.append(f"{size}x")
        self.off += size

    def flush(self) -> None:
        if self.vars:
            s = self.c.struct(self.codes)
            where = f"pos + {self.run_at}" if self.run_at else "pos"
            self.emit(f"{', '.join(self.vars)}, = {s}.unpack_from(buf, {where})")
        self.codes, self.vars = [], []

    def settle(self) -> None:
        """Flush, then fold the static offset into ``pos``."""
        self.flush()
        if self.off:
            self.emit(f"pos += {self.off}")
            self.off = 0

    def count(self, ft: Int) -> str:
        var = self.take(ft.struct_code, ft.size)
        self.flush()
        return var

    def counted(self, n: str) -> tuple[str, str]:
        """Bounds-check ``n`` bytes at the current position; ``(start, end)`` expressions."""
        start = self.at()
        end = self.c.name("e")
        self.emit(f"{end} = {start} + {n}")
        self.emit(f"if {end} > len(buf):")
        self.emit("    raise Reject")
        return start, end

    def dec(self, ft: FieldType) -> str:
        if isinstance(ft, Int | Float):
            return self.take(ft.struct_code, ft.size)
        if isinstance(ft, Scaled):
            scale, bias = scaling(ft)
            var = self.take(ft.raw.struct_code, ft.raw.size)
            if bias == 0.0:
                return f"{var} * {scale!r}"
            return f"({var} * {scale!r} + {bias!r})"
        if isinstance(ft, Enum):
            return self.take(ft.raw.struct_code, ft.raw.size)
        if isinstance(ft, BitField):
            var = self.take(ft.raw.struct_code, ft.raw.size)
            items = []
            for sub in ft.subfields:
                mask = subfield_mask(sub.lo, sub.hi)
                shifted = f"({var} >> {sub.lo})" if sub.lo else var
                items.append(f"{sub.name!r}: {shifted} & {mask}")
            return "{" + ", ".join(items) + "}"
        if isinstance(ft, FixedString):
            var = self.take(f"{ft.length}s", ft.length)
            return f"{var}.rstrip(b'\\x00').decode('latin-1')"
        if isinstance(ft, FixedBytes):
            return self.take(f"{ft.length}s", ft.length)
        if isinstance(ft, VarString | VarBytes | JausMessage):
            n = self.count(ft.count)
            if isinstance(ft, JausMessage):
                self.emit(f"if {n} < 2:")
                self.emit("    raise Reject")
            start, end = self.counted(n)
            var = self.c.name("s")
            tail = ".decode('latin-1')" if isinstance(ft, VarString) else ""
            self.emit(f"{var} = buf[{start}:{end}]{tail}")
            self.emit(f"pos = {end}")
            self.off = 0
            return var
        if isinstance(ft, VarFormat):
            fmt = self.take(ft.format.raw.struct_code, ft.format.raw.size)
            n = self.count(ft.count)
            start, end = self.counted(n)
            var = self.c.name("s")
            self.emit(f"{var} = buf[{start}:{end}]")
            self.emit(f"pos = {end}")
            self.off = 0
            return f"{{'format': {fmt}, 'data': {var}}}"
        if isinstance(ft, Record):
            if ft.pv is None:
                return self.record_fields(ft, -1)
            return self._pv_record(ft)
        if isinstance(ft, List):
            return self._list(ft)
        if isinstance(ft, Variant):
            tag = self.count(ft.tag)
            table = self.c.variant_decoders(ft)
            fn, var = self.c.name("f"), self.c.name("r")
            self.emit(f"{fn} = {table}.get({tag})")
            self.emit(f"if {fn} is None:")
            self.emit("    raise Reject")
            self.emit(f"{var}, pos = {fn}(buf, {self.at()})")
            self.off = 0
            return var
        raise TypeError(f"not a field type: {ft!r}")

    def record_fields(self, rec: Record, pv: int) -> str:
        """Dict display of the fields present under presence vector ``pv`` (-1: all)."""
        items = []
        bit = 0
        for fld in rec.fields:
            if fld.optional:
                here = pv >> bit & 1
                bit += 1
                if not here:
                    continue
            items.append(f"{fld.name!r}: {self.dec(fld.type)}")
        return "{" + ", ".join(items) + "}"

    def _pv_record(self, rec: Record) -> str:
        assert rec.pv is not None
        self.flush()
        cache, miss = self.c.pv_record_decoder(rec)
        pv, fn, var = self.c.name("pv"), self.c.name("f"), self.c.name("r")
        here = self.at()
        if rec.pv.bits == 8:
            self.emit(f"{pv} = buf[{here}]")
        elif rec.pv.bits == 16:
            self.emit(f"{pv} = buf[{here}] | buf[{here} + 1] << 8")
        else:
            s = self.c.struct([rec.pv.struct_code])
            self.emit(f"{pv} = {s}.unpack_from(buf, {here})[0]")
        self.emit(f"{fn} = {cache}.get({pv})")
        self.emit(f"if {fn} is None:")
        self.emit(f"    {fn} = {miss}({pv})")
        self.emit(f"{var}, pos = {fn}(buf, {here})")
        self.off = 0
        return var

    def _list(self, ft: List) -> str:
        n = self.count(ft.count)
        var = self.c.name("l")
        size = fixed_size(ft.element)
        if size:
            sub = _DecBlock(self.c, [], 0)
            expr = sub.dec(ft.element)
            assert not sub.lines, "a fixed-size element never ends a struct run"
            s = self.c.struct(sub.codes)
            start, end = self.c.name("b"), self.c.name("e")
            self.emit(f"{start} = {self.at()}")
            self.emit(f"{end} = {start} + {n} * {size}")
            self.emit(f"if {end} > len(buf):")
            self.emit("    raise Reject")
            target = ", ".join(sub.vars) + ","
            self.emit(f"{var} = [{expr} for {target} in {s}.iter_unpack(buf[{start}:{end}])]")
            self.emit(f"pos = {end}")
            self.off = 0
            return var
        self.settle()
        each = max(min_size(ft.element), 1)
        self.emit(f"if {n} * {each} > len(buf) - pos:")
        self.emit("    raise Reject")
        self.emit(f"{var} = []")
        self.emit(f"for _ in range({n}):")
        inner = _DecBlock(self.c, self.lines, self.indent + 1)
        expr = inner.dec(ft.element)
        inner.flush()
        inner.emit(f"{var}.append({expr})")
        if inner.off:
            inner.emit(f"pos += {inner.off}")
        return var


class _EncBlock(_Block):
    """Encoding statements; fixed-size values accumulate into one pending ``pack`` call."""

    def __init__(self, comp: Compiler, lines: list[str], indent: int) -> None:
        super().__init__(comp, lines, indent)
        self.codes: list[str] = []
        self.args: list[str] = []
        self.uses_out = False
        self.opening = len(lines)

    def add(self, code: str, arg: str) -> None:
        self.codes.append(code)
        self.args.append(arg)

    def flush(self) -> None:
        if self.codes:
            s = self.c.struct(self.codes)
            self.emit(f"out += {s}.pack({', '.join(self.args)})")
            self.uses_out = True
        self.codes, self.args = [], []

    def finish_bytes(self) -> None:
        """End a function that returns the encoded bytes."""
        if not self.uses_out:
            s = self.c.struct(self.codes)
            self.emit(f"return {s}.pack({', '.join(self.args)})")
            self.codes, self.args = [], []
            return
        self.lines.insert(self.opening, "    " * self.indent + "out = bytearray()")
        self.flush()
        self.emit("return bytes(out)")

    def bind(self, expr: str) -> str:
        if expr.isidentifier():
            return expr
        var = self.c.name("t")
        self.emit(f"{var} = {expr}")
        return var

    def enc(self, ft: FieldType, v: str) -> None:
        if isinstance(ft, Int | Float):
            self.add(ft.struct_code, v)
        elif isinstance(ft, Scaled):
            scale, bias = scaling(ft)
            if bias == 0.0:
                self.add(ft.raw.struct_code, f"round({v} / {scale!r})")
            else:
                self.add(ft.raw.struct_code, f"round(({v} - {bias!r}) / {scale!r})")
        elif isinstance(ft, Enum):
            self.add(ft.raw.struct_code, v)
        elif isinstance(ft, BitField):
            self.add(ft.raw.struct_code, f"{self.c.bitfield_packer(ft)}({v})")
        elif isinstance(ft, FixedString):
            t = self.c.name("t")
            self.emit(f"{t} = {v}.encode('latin-1')")
            self.emit(f"if len({t}) > {ft.length}:")
            self.emit("    raise Reject")
            self.add(f"{ft.length}s", t)
        elif isinstance(ft, FixedBytes):
            t = self.bind(v)
            self.emit(f"if not isinstance({t}, _BYTES) or len({t}) != {ft.length}:")
            self.emit("    raise Reject")
            self.add(f"{ft.length}s", t)
        elif isinstance(ft, VarString):
            t = self.c.name("t")
            self.emit(f"{t} = {v}.encode('latin-1')")
            if ft.max_length is not None:
                self.emit(f"if len({t}) > {ft.max_length}:")
                self.emit("    raise Reject")
            self.add(ft.count.struct_code, f"len({t})")
            self.flush()
            self.emit(f"out += {t}")
        elif isinstance(ft, VarBytes | JausMessage):
            t = self.bind(v)
            short = f" or len({t}) < 2" if isinstance(ft, JausMessage) else ""
            self.emit(f"if not isinstance({t}, _BYTES){short}:")
            self.emit("    raise Reject")
            self.add(ft.count.struct_code, f"len({t})")
            self.flush()
            self.emit(f"out += {t}")
        elif isinstance(ft, VarFormat):
            r = self.bind(v)
            self.emit(f"if len({r}) != 2:")
            self.emit("    raise Reject")
            d = self.bind(f"{r}['data']")
            self.emit(f"if not isinstance({d}, _BYTES):")
            self.emit("    raise Reject")
            self.add(ft.format.raw.struct_code, f"{r}['format']")
            self.add(ft.count.struct_code, f"len({d})")
            self.flush()
            self.emit(f"out += {d}")
        elif isinstance(ft, Record):
            r = self.bind(v)
            if ft.pv is None:
                self.emit(f"if len({r}) != {len(ft.fields)}:")
                self.emit("    raise Reject")
                self.record_fields(ft, r, -1)
            else:
                cache, miss = self.c.pv_record_encoder(ft)
                pv, fn = self.c.name("pv"), self.c.name("f")
                self.emit(f"{pv} = {_pv_expr(ft, r)}")
                self.flush()
                self.emit(f"{fn} = {cache}.get({pv})")
                self.emit(f"if {fn} is None:")
                self.emit(f"    {fn} = {miss}({pv})")
                self.emit(f"{fn}({r}, out)")
                self.uses_out = True
        elif isinstance(ft, List):
            t = self.bind(v)
            self.emit(f"if not isinstance({t}, _SEQ):")
            self.emit("    raise Reject")
            self.add(ft.count.struct_code, f"len({t})")
            self.flush()
            item = self.c.name("i")
            self.emit(f"for {item} in {t}:")
            inner = _EncBlock(self.c, self.lines, self.indent + 1)
            inner.enc(ft.element, item)
            inner.flush()
            if len(self.lines) and self.lines[-1].endswith(":"):
                inner.emit("pass")
        elif isinstance(ft, Variant):
            r = self.bind(v)
            table = self.c.variant_encoders(ft)
            k, x = self.c.name("k"), self.c.name("x")
            self.emit(f"(({k}, {x}),) = {r}.items()")
            self.flush()
            self.emit(f"{table}[{k}]({x}, out)")
            self.uses_out = True
        else:
            raise TypeError(f"not a field type: {ft!r}")

    def record_fields(self, rec: Record, r: str, pv: int) -> None:
        bit = 0
        for fld in rec.fields:
            if fld.optional:
                here = pv >> bit & 1
                bit += 1
                if not here:
                    continue
            self.enc(fld.type, f"{r}[{fld.name!r}]")
