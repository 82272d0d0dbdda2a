"""DDS Security for one participant, as participant QoS properties. No I/O.

Cyclone DDS reads its security settings either from the ``<Security>`` element of its XML
configuration or from ``dds.sec.*`` properties of the participant QoS; edge-vis uses the
properties, so each participant carries its own identity and the domain's network
configuration (``CYCLONEDDS_URI``, :func:`~edge_vis.dds.cyclone_config.loopback_config`)
stays as it is. The plugins are the three of the DDS Security specification, as Debian's
Cyclone DDS package ships them (``libdds_security_{auth,crypto,ac}``); the Cyclone DDS
wheel from PyPI is built without them (``scripts/setup.sh --secure`` builds a binding
that has them).
"""

from __future__ import annotations

from cyclonedds import __library__ as _library
from cyclonedds.qos import Policy, Qos

from edge_vis.config.deployment import DdsSecurityProfile

_PLUGINS = {
    "auth": ("dds_security_auth", "init_authentication", "finalize_authentication"),
    "crypto": ("dds_security_crypto", "init_crypto", "finalize_crypto"),
    "access": ("dds_security_ac", "init_access_control", "finalize_access_control"),
}
#: how to get a binding with the security plugins, for error messages
HOW_TO_SECURE = ("this Cyclone DDS build has no DDS Security (the PyPI wheel is built "
                 "without it): set up with scripts/setup.sh --secure and use .venv-secure")


def security_available() -> bool:
    """True when the binding loads a system Cyclone DDS (Debian's ships the security
    plugins) rather than the library bundled in the PyPI wheel (which has none)."""
    return getattr(_library, "in_wheel", True) is False


def security_properties(settings: DdsSecurityProfile) -> dict[str, str]:
    """The ``dds.sec.*`` participant properties of ``settings`` (files as ``file:`` URIs)."""
    props: dict[str, str] = {}
    for plugin, (library, init, finalize) in _PLUGINS.items():
        props[f"dds.sec.{plugin}.library.path"] = library
        props[f"dds.sec.{plugin}.library.init"] = init
        props[f"dds.sec.{plugin}.library.finalize"] = finalize
    files = {
        "dds.sec.auth.identity_ca": settings.identity_ca,
        "dds.sec.auth.identity_certificate": settings.certificate,
        "dds.sec.auth.private_key": settings.private_key,
        "dds.sec.access.permissions_ca": settings.permissions_ca,
        "dds.sec.access.governance": settings.governance,
        "dds.sec.access.permissions": settings.permissions,
        "org.eclipse.cyclonedds.sec.auth.crl": settings.crl,
    }
    for key, path in files.items():
        if path is not None:
            props[key] = f"file:{path.resolve()}"
    return props


def participant_qos(settings: DdsSecurityProfile) -> Qos:
    """The participant QoS that makes a participant join with ``settings``."""
    return Qos(*(Policy.Property(k, v) for k, v in security_properties(settings).items()))


__all__ = ["HOW_TO_SECURE", "participant_qos", "security_available", "security_properties"]
