"""Per-vehicle pre-shared keys of the bulk channel, from a key file. Reads a file.

The file is TOML with one hex key per vehicle id (at least 16 bytes = 32 hex digits; make
them with ``python -c "import secrets; print(secrets.token_hex(32))"``)::

    [keys]
    uuv-delta = "4f1c...e9"

The receiver (``receive-images --keys``) accepts images only from the vehicles listed and
only when the sender proves it holds that vehicle's key; the sender (``send-image
--keys``) uses the key of its ``--vehicle``. Keep the file readable by the service
account only: a warning is logged when group or others may read it.
"""

from __future__ import annotations

import logging
import os
import re
import stat
import tomllib
from pathlib import Path

from edge_vis.errors import ConfigError
from links.udt.protocol import MIN_KEY_BYTES

log = logging.getLogger(__name__)

_HEX = re.compile(r"^[0-9a-fA-F]+$")


def parse_keys(data: object, file: str = "") -> dict[str, bytes]:
    """Validate a parsed key table; raise ConfigError listing every problem."""
    problems: list[tuple[str, str, str]] = []
    keys: dict[str, bytes] = {}
    if not isinstance(data, dict) or set(data) - {"keys"}:
        extra = sorted(set(data) - {"keys"}) if isinstance(data, dict) else []
        problems.append((file, extra[0] if extra else "", "expected only a [keys] table"))
        data = {}
    table = data.get("keys", {})
    if not isinstance(table, dict):
        problems.append((file, "keys", "expected a table of vehicle_id = \"hex key\""))
        table = {}
    for vehicle_id, value in table.items():
        path = f"keys.{vehicle_id}"
        if not isinstance(value, str) or not _HEX.match(value) or len(value) % 2:
            problems.append((file, path, "expected the key as an even number of hex digits"))
            continue
        key = bytes.fromhex(value)
        if len(key) < MIN_KEY_BYTES:
            problems.append((file, path, f"key of {len(key)} bytes is too short "
                                         f"(at least {MIN_KEY_BYTES})"))
            continue
        keys[vehicle_id] = key
    if problems:
        raise ConfigError(problems)
    return keys


def load_keys(path: str | os.PathLike[str]) -> dict[str, bytes]:
    """Read the key file at ``path``; ConfigError when it is unreadable or invalid."""
    p = Path(path)
    try:
        raw = p.read_bytes()
        mode = p.stat().st_mode
    except OSError as exc:
        raise ConfigError([(str(p), "", f"cannot read: {exc.strerror or exc}")]) from exc
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError([(str(p), "", f"invalid TOML: {exc}")]) from exc
    if mode & (stat.S_IRGRP | stat.S_IROTH):
        log.warning("key file %s is readable by group or others; chmod 600 it", p)
    return parse_keys(data, str(p))


__all__ = ["load_keys", "parse_keys"]
