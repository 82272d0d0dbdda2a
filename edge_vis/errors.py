"""The edge-vis exception tree. No I/O.

Every error edge-vis raises on purpose derives from :class:`EdgeVisError`::

    EdgeVisError
    ├── ConfigError            a profile is invalid (file, key path, problem); fatal at start-up
    ├── PluginError
    │   ├── PluginNotFoundError    no entry point of that name is installed
    │   ├── PluginLoadError        the entry point exists but failed to import
    │   └── PluginConflictError    two plugins claim the same message code or topic
    ├── CodecError
    │   ├── DecodeError        the *remote* sent bytes we cannot decode (code, field path, offset)
    │   ├── EncodeError        *we* tried to encode a value the definition cannot carry
    │   └── UnsupportedError   well-formed but not supported (e.g. JUDP header compression)
    ├── ProtocolViolation
    │   ├── RemoteProtocolError    a peer broke a JAUS rule
    │   └── LocalProtocolError     we were about to break one
    └── LinkError              an I/O failure of a link (wraps OSError / serial errors)

Bad bytes from a radio must never crash the relay: the shell counts and drops a
``DecodeError``. Bad configuration must stop it at start-up with a ``ConfigError``.
"""

from __future__ import annotations


class EdgeVisError(Exception):
    """Root of every error edge-vis raises deliberately."""


class ConfigError(EdgeVisError):
    """A profile is invalid.

    ``problems`` lists every ``(file, key_path, message)`` found, so a user can fix them
    all at once rather than one per run.
    """

    def __init__(self, problems: list[tuple[str, str, str]] | str) -> None:
        if isinstance(problems, str):
            problems = [("", "", problems)]
        self.problems = problems
        super().__init__(
            "\n".join(
                ": ".join(part for part in (f, k, m) if part) for f, k, m in problems
            )
        )


class PluginError(EdgeVisError):
    """A link, translator or message-set plugin could not be used."""


class PluginNotFoundError(PluginError):
    """No plugin of that name is installed in the entry-point group."""


class PluginLoadError(PluginError):
    """The plugin exists but importing or validating it failed."""


class PluginConflictError(PluginError):
    """Two plugins claim the same JAUS message code or DDS topic."""


class CodecError(EdgeVisError):
    """Base for wire encoding and decoding errors."""


class DecodeError(CodecError):
    """Bytes that do not decode.

    Carries the message code (when known), the field path inside the message
    (``"fields[2].range"``) and the byte offset from the start of the decoded unit.
    """

    def __init__(
        self,
        reason: str,
        *,
        code: int | None = None,
        path: str = "",
        offset: int | None = None,
    ) -> None:
        self.reason = reason
        self.code = code
        self.path = path
        self.offset = offset
        parts = []
        if code is not None:
            parts.append(f"message 0x{code:04X}")
        if path:
            parts.append(f"field {path}")
        if offset is not None:
            parts.append(f"offset {offset}")
        where = f" ({', '.join(parts)})" if parts else ""
        super().__init__(f"{reason}{where}")


class EncodeError(CodecError):
    """A value that the message definition cannot carry (out of range, wrong type)."""

    def __init__(self, reason: str, *, code: int | None = None, path: str = "") -> None:
        self.reason = reason
        self.code = code
        self.path = path
        parts = []
        if code is not None:
            parts.append(f"message 0x{code:04X}")
        if path:
            parts.append(f"field {path}")
        where = f" ({', '.join(parts)})" if parts else ""
        super().__init__(f"{reason}{where}")


class UnsupportedError(DecodeError):
    """Well-formed input using a feature edge-vis does not support (e.g. header compression)."""


class ProtocolViolation(EdgeVisError):
    """A JAUS protocol rule was broken."""


class RemoteProtocolError(ProtocolViolation):
    """A peer broke a JAUS rule (for instance, a report for an event we never created)."""


class LocalProtocolError(ProtocolViolation):
    """edge-vis was about to break a JAUS rule (for instance, command without control)."""


class LinkError(EdgeVisError):
    """An I/O failure of a link; the link reports it and the relay keeps running."""
