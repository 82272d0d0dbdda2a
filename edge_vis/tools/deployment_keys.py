"""A deployment's DDS Security material, from its relay profile. Performs I/O (files, openssl).

Layout of the security directory (``edge-vis security init``)::

    ca/                 the deployment CA: ca.pem (give to everyone), ca.key (guard it),
                        crl.pem (revocation list, give to everyone), openssl's index
    governance.xml/.p7s the rules for the domain, signed
    relay/NAME/         key.pem, cert.pem, permissions.xml/.p7s, cyclonedds.xml
    operator/ID/        the same, for each [[operators]] id of the profile
    observer/NAME/      the same, read-only (monitors, displays)

``cyclonedds.xml`` is a Cyclone DDS configuration with the identity's security settings,
for an operator station's own DDS application (``CYCLONEDDS_URI=file://...``). Cyclone
0.10 takes the revocation list only as a participant QoS property
(``org.eclipse.cyclonedds.sec.auth.crl``), not in this file; edge-vis sets it from
``[dds.security] crl``.
"""

from __future__ import annotations

import contextlib
import datetime
import fnmatch
import re
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from edge_vis.config import RelayProfile
from edge_vis.config.deployment import DdsSecurityProfile
from edge_vis.engine.manager import TranslationManager
from edge_vis.tools.access_documents import (
    OBSERVER,
    OPERATOR,
    RELAY,
    Grant,
    governance_xml,
    permissions_xml,
)
from edge_vis.tools.pki import (
    CertificateAuthority,
    PkiError,
    certificate_subject,
    check_private_key,
    verify_certificate,
    verify_document,
)

_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
_TIME = "%Y-%m-%dT%H:%M:%S"

_CYCLONE_XML = """\
<?xml version="1.0" encoding="UTF-8"?>
<CycloneDDS xmlns="https://cdds.io/config"><Domain id="any"><Security>
  <Authentication>
    <Library path="dds_security_auth" initFunction="init_authentication"
             finalizeFunction="finalize_authentication"/>
    <IdentityCA>file:{ca}</IdentityCA>
    <IdentityCertificate>file:{cert}</IdentityCertificate>
    <PrivateKey>file:{key}</PrivateKey>
  </Authentication>
  <Cryptographic>
    <Library path="dds_security_crypto" initFunction="init_crypto"
             finalizeFunction="finalize_crypto"/>
  </Cryptographic>
  <AccessControl>
    <Library path="dds_security_ac" initFunction="init_access_control"
             finalizeFunction="finalize_access_control"/>
    <PermissionsCA>file:{ca}</PermissionsCA>
    <Governance>file:{governance}</Governance>
    <Permissions>file:{permissions}</Permissions>
  </AccessControl>
</Security></Domain></CycloneDDS>
"""


@dataclass(frozen=True, slots=True)
class Identity:
    """One participant's files in the security directory."""

    role: str
    name: str
    directory: Path

    @property
    def cert(self) -> Path:
        return self.directory / "cert.pem"

    @property
    def key(self) -> Path:
        return self.directory / "key.pem"

    @property
    def permissions(self) -> Path:
        return self.directory / "permissions.p7s"


class SecurityDirectory:
    """The security directory of one deployment (see the module docstring)."""

    def __init__(self, directory: Path) -> None:
        self.directory = directory
        self.ca = CertificateAuthority(directory / "ca")
        self.governance = directory / "governance.p7s"

    def identity(self, role: str, name: str) -> Identity:
        if not _NAME.fullmatch(name):
            raise PkiError(f"{name!r}: a name for DDS Security must be letters, digits, "
                           f"'_', '.' or '-' (it becomes a DDS partition and a subject)")
        return Identity(role, name, self.directory / role / name)

    def identities(self) -> list[Identity]:
        """Every identity issued so far, relays first."""
        return [Identity(role, d.name, d) for role in (RELAY, OPERATOR, OBSERVER)
                for d in sorted((self.directory / role).glob("*"))
                if (d / "cert.pem").exists()]

    def find(self, name: str) -> Identity:
        found = [i for i in self.identities() if i.name == name or
                 f"{i.role}/{i.name}" == name]
        if len(found) != 1:
            have = ", ".join(f"{i.role}/{i.name}" for i in self.identities())
            why = "ambiguous, say ROLE/NAME" if found else "no such identity"
            raise PkiError(f"{name!r}: {why} (have {have or 'none'})")
        return found[0]

    # -- issuing ---------------------------------------------------------------------------
    def issue_all(self, profile: RelayProfile, organization: str, *,
                  observers: Sequence[str] = (), days: int = 365,
                  renew: bool = False) -> list[Identity]:
        """Create the CA if absent, then the governance and, for the relay, each listed
        operator and each observer, a certificate (new, or renewed with ``renew``) and
        permissions. Returns the identities written."""
        if not self.ca.key.exists():
            CertificateAuthority.create(self.ca.directory, organization)
        self.ca.open()
        domain = profile.dds.domain
        xml = self.directory / "governance.xml"
        xml.write_text(governance_xml(domain))
        self.ca.sign(xml, self.governance)
        wanted = [self.identity(RELAY, profile.name)]
        wanted += [self.identity(OPERATOR, op) for op in profile.operators.operators]
        wanted += [self.identity(OBSERVER, name) for name in observers]
        commands = sorted(set(TranslationManager.from_selection(profile.translators)
                              .topics()[1]))
        now = datetime.datetime.now(datetime.UTC).replace(microsecond=0)
        until = now + datetime.timedelta(days=days)
        for ident in wanted:
            if renew or not ident.cert.exists():
                self.ca.issue(ident.directory, organization, f"{ident.role}.{ident.name}",
                              days=days)
            grant = Grant(certificate_subject(ident.cert), ident.role, ident.name,
                          now.strftime(_TIME), until.strftime(_TIME))
            doc = ident.directory / "permissions.xml"
            doc.write_text(permissions_xml([grant], domain, profile.dds.partitions, commands))
            self.ca.sign(doc, ident.permissions)
            (ident.directory / "cyclonedds.xml").write_text(self.cyclone_xml(ident))
        return wanted

    def cyclone_xml(self, ident: Identity) -> str:
        return _CYCLONE_XML.format(
            ca=self.ca.cert.resolve(), cert=ident.cert.resolve(), key=ident.key.resolve(),
            crl=self.ca.crl.resolve(), governance=self.governance.resolve(),
            permissions=ident.permissions.resolve())

    def profile_for(self, ident: Identity) -> DdsSecurityProfile:
        """The ``[dds.security]`` settings of ``ident`` (absolute paths)."""
        return DdsSecurityProfile(
            identity_ca=self.ca.cert.resolve(), certificate=ident.cert.resolve(),
            private_key=ident.key.resolve(), permissions_ca=self.ca.cert.resolve(),
            governance=self.governance.resolve(), permissions=ident.permissions.resolve(),
            crl=self.ca.crl.resolve())

    def revoke(self, ident: Identity) -> None:
        self.ca.open().revoke(ident.cert)


def security_table(settings: DdsSecurityProfile, relative_to: Path | None = None) -> str:
    """``settings`` as the ``[dds.security]`` TOML table, paths relative to the profile."""
    lines = ["[dds.security]"]
    for key in ("identity_ca", "certificate", "private_key", "permissions_ca", "governance",
                "permissions", "crl"):
        path = getattr(settings, key)
        if path is None:
            continue
        if relative_to is not None:
            with contextlib.suppress(ValueError):  # outside the profile's folder: absolute
                path = path.relative_to(relative_to.resolve())
        lines.append(f'{key} = "{path}"')
    return "\n".join(lines) + "\n"


def _domains(rule: ET.Element) -> list[tuple[int, int]]:
    """The ``<domains>`` of a governance domain_rule or permissions allow_rule, as ranges."""
    out = []
    for ident in rule.iterfind("domains/id"):
        out.append((int(ident.text or -1), int(ident.text or -1)))
    for span in rule.iterfind("domains/id_range"):
        low, high = span.findtext("min"), span.findtext("max")
        out.append((int(low or 0), int(high) if high else 1 << 31))
    return out


def _covers(ranges: list[tuple[int, int]], domain: int) -> bool:
    return any(low <= domain <= high for low, high in ranges)


def _document_problems(governance: str, permissions: str, subject: str, domain: int,
                       partitions: Sequence[str]) -> list[tuple[str, str]]:
    """What keeps a relay (``subject``) in ``domain`` and ``partitions`` from joining and
    publishing under these documents (made for another domain or other partitions)."""
    problems: list[tuple[str, str]] = []
    try:
        rules = ET.fromstring(governance).iterfind("domain_access_rules/domain_rule")
        if not any(_covers(_domains(rule), domain) for rule in rules):
            problems.append(("governance", f"has no rule for the profile's DDS domain {domain} "
                             "(made for another [dds] domain? run edge-vis security init "
                             "again)"))
        grants = [g for g in ET.fromstring(permissions).iterfind("permissions/grant")
                  if (g.findtext("subject_name") or "").strip() == subject]
    except (ET.ParseError, ValueError) as exc:
        return [("permissions", f"signed, but not a DDS Security document: {exc}")]
    if not grants:
        return [*problems, ("permissions", f"grants nothing to the certificate's subject "
                                           f"{subject}")]
    allowed = [rule for grant in grants for rule in grant.iterfind("allow_rule")
               if _covers(_domains(rule), domain)]
    if not allowed:
        problems.append(("permissions", f"allow nothing in the profile's DDS domain {domain} "
                         "(made for another [dds] domain? run edge-vis security init again)"))
        return problems
    patterns = [(p.text or "") for rule in allowed for p in rule.iterfind("publish/partitions/"
                                                                          "partition")]
    if any(rule.find("publish") is not None and rule.find("publish/partitions") is None
           for rule in allowed):
        patterns.append("")  # a rule without <partitions>: the default partition
    denied = [p or "(default)" for p in partitions or ("",)
              if not any(fnmatch.fnmatchcase(p, pattern) for pattern in patterns)]
    if denied:
        problems.append(("permissions", "do not let the relay publish in the profile's "
                         f"partition(s) {', '.join(denied)} (made for other [dds] partitions? "
                         "run edge-vis security init again)"))
    return problems


def security_problems(settings: DdsSecurityProfile, where: str = "dds.security", *,
                      domain: int | None = None,
                      partitions: Sequence[str] = ()) -> list[tuple[str, str]]:
    """``(key, problem)`` for every file of ``settings`` that is missing, does not parse,
    is not signed by its CA, has expired or been revoked, or does not name the
    certificate's subject; with ``domain``, also documents made for another domain or
    other ``partitions`` (the relay's); empty when the relay can join securely."""
    problems: list[tuple[str, str]] = []
    for key in ("identity_ca", "certificate", "private_key", "permissions_ca", "governance",
                "permissions", "crl"):
        path = getattr(settings, key)
        if path is not None and not Path(path).is_file():
            problems.append((f"{where}.{key}", f"{path}: no such file"))
    if problems:
        return problems

    def attempt(key: str, what: str, check: object) -> object:
        try:
            return check()  # type: ignore[operator]
        except PkiError as exc:
            problems.append((f"{where}.{key}", f"{what} ({exc})" if what else str(exc)))
            return None

    identity_ca, permissions_ca = settings.identity_ca, settings.permissions_ca
    attempt("certificate", f"not valid under the identity CA {identity_ca}: not issued by "
            "it, expired or revoked", lambda: verify_certificate(
                identity_ca, settings.certificate, settings.crl))
    attempt("private_key", "", lambda: check_private_key(settings.private_key,
                                                         settings.certificate))
    governance = attempt("governance", f"not signed by the permissions CA {permissions_ca}",
                         lambda: verify_document(permissions_ca, settings.governance))
    text = attempt("permissions", f"not signed by the permissions CA {permissions_ca}",
                   lambda: verify_document(permissions_ca, settings.permissions))
    subject = attempt("certificate", "", lambda: certificate_subject(settings.certificate))
    if isinstance(text, str) and isinstance(subject, str) and \
            f"<subject_name>{subject}</subject_name>" not in text:
        problems.append((f"{where}.permissions",
                         f"grants nothing to the certificate's subject {subject}"))
    elif isinstance(text, str) and isinstance(subject, str) and \
            isinstance(governance, str) and domain is not None:
        problems += [(f"{where}.{key}", problem) for key, problem in _document_problems(
            governance, text, subject, domain, partitions)]
    return problems


__all__ = ["Identity", "SecurityDirectory", "security_problems", "security_table"]
