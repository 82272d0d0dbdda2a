"""A small deployment PKI for DDS Security, on the ``openssl`` command line. Performs I/O.

DDS Security needs three kinds of signed material, all checked by the Cyclone DDS security
plugins with OpenSSL: X.509 identity certificates (issued by the *identity CA*), and the
governance and permissions XML documents as S/MIME messages signed by the *permissions
CA*. One deployment CA plays both roles here, so a deployment has one key to guard.

The CA is an ordinary ``openssl ca`` directory (``index.txt`` of every certificate issued,
``serial``, ``crlnumber``), so revoking is ``openssl ca -revoke`` and the revocation list
(``crl.pem``) is what every participant loads. Keys are EC P-256 (what Cyclone's
handshake signs with fastest). Nothing here holds a key in Python memory: every
operation runs ``openssl`` on files.
"""

from __future__ import annotations

import re
import shlex
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

from edge_vis.errors import EdgeVisError

#: the deployment CA's files inside its directory
CA_CERT = "ca.pem"
CA_KEY = "ca.key"
CRL = "crl.pem"


class PkiError(EdgeVisError):
    """An ``openssl`` operation failed or a file is not what it should be."""


def _openssl(*args: str, stdin: bytes | None = None) -> str:
    exe = shutil.which("openssl")
    if exe is None:
        raise PkiError("the openssl command is needed (Debian: apt-get install openssl)")
    done = subprocess.run([exe, *args], input=stdin, capture_output=True, check=False)
    if done.returncode != 0:
        command = " ".join(shlex.quote(a) for a in ("openssl", *args))
        why = openssl_complaint(done.stdout.decode(errors="replace"),
                                done.stderr.decode(errors="replace"))
        raise PkiError(f"`{command}` failed (exit {done.returncode}): {why or 'no message'}")
    return done.stdout.decode(errors="replace")


#: an OpenSSL 3 error-queue line: ``thread:error:code:library:function:reason:file:line:data``
_QUEUE_LINE = re.compile(r"^[0-9A-F]+:error:[0-9A-F]+:[^:]*:[^:]*:([^:]*):[^:]*:\d+:(.*)$")


def openssl_complaint(stdout: str, stderr: str) -> str:
    """What a failed ``openssl`` command said, on one line: its whole stderr, with each
    error-queue line cut to its reason (and extra data), and ``openssl verify``'s verdict,
    which it prints on stdout (``error 23 at 0 depth lookup: certificate revoked``)."""
    said = [line.strip() for line in stdout.splitlines() if line.startswith("error ")]
    for line in stderr.splitlines():
        line = line.strip()
        match = _QUEUE_LINE.match(line)
        if match:
            line = ": ".join(part for part in match.groups() if part)
        if line and line not in said:
            said.append(line)
    return "; ".join(said)


_CA_CONFIG = """\
[ ca ]
default_ca = deployment
[ deployment ]
dir = {dir}
database = $dir/index.txt
new_certs_dir = $dir/issued
certificate = $dir/{cert}
private_key = $dir/{key}
serial = $dir/serial
crlnumber = $dir/crlnumber
default_md = sha256
default_days = 365
default_crl_days = {crl_days}
policy = any_name
unique_subject = no
copy_extensions = none
x509_extensions = identity
[ any_name ]
organizationName = optional
commonName = supplied
[ identity ]
basicConstraints = critical,CA:FALSE
keyUsage = critical,digitalSignature,keyAgreement
[ req ]
distinguished_name = req_dn
[ req_dn ]
[ ca_ext ]
basicConstraints = critical,CA:TRUE
keyUsage = critical,keyCertSign,cRLSign,digitalSignature
subjectKeyIdentifier = hash
"""


def subject_dn(organization: str, common_name: str) -> str:
    """The subject in the RFC 4514 form permissions documents carry (``CN=..,O=..``)."""
    return f"CN={common_name},O={organization}"


def _subj_arg(organization: str, common_name: str) -> str:
    for part in (organization, common_name):
        if any(c in part for c in "/,=+\\\"<>;"):
            raise PkiError(f"{part!r}: a name may not contain / , = + \\ \" < > ;")
    return f"/O={organization}/CN={common_name}"


@dataclass(frozen=True, slots=True)
class CertificateAuthority:
    """A deployment CA kept in ``directory`` (created by :meth:`create`)."""

    directory: Path

    @property
    def cert(self) -> Path:
        return self.directory / CA_CERT

    @property
    def key(self) -> Path:
        return self.directory / CA_KEY

    @property
    def crl(self) -> Path:
        return self.directory / CRL

    @property
    def _config(self) -> Path:
        return self.directory / "openssl.cnf"

    @classmethod
    def create(cls, directory: Path, organization: str, *, days: int = 3650,
               crl_days: int = 365) -> CertificateAuthority:
        """A new CA (refused if ``directory`` already holds one: it would orphan every
        identity it issued)."""
        ca = cls(directory)
        if ca.key.exists():
            raise PkiError(f"{directory} already holds a CA ({CA_KEY}); keep it or remove it")
        (directory / "issued").mkdir(parents=True, exist_ok=True)
        (directory / "index.txt").write_text("")
        (directory / "serial").write_text("1000\n")
        (directory / "crlnumber").write_text("1000\n")
        ca._config.write_text(_CA_CONFIG.format(dir=directory.resolve(), cert=CA_CERT,
                                                key=CA_KEY, crl_days=crl_days))
        _openssl("ecparam", "-name", "prime256v1", "-genkey", "-noout", "-out", str(ca.key))
        ca.key.chmod(0o600)
        _openssl("req", "-new", "-x509", "-sha256", "-days", str(days), "-config",
                 str(ca._config), "-extensions", "ca_ext", "-key", str(ca.key),
                 "-subj", _subj_arg(organization, f"{organization} CA"), "-out", str(ca.cert))
        ca.update_crl()
        return ca

    def open(self) -> CertificateAuthority:
        """Check the CA is there (certificate and key)."""
        for path in (self.cert, self.key, self._config):
            if not path.is_file():
                raise PkiError(f"no CA in {self.directory}: {path.name} missing "
                               f"(create one with edge-vis security init)")
        return self

    def issue(self, directory: Path, organization: str, common_name: str, *,
              days: int = 365) -> Path:
        """A new key and certificate for ``common_name`` in ``directory`` (``key.pem``,
        ``cert.pem``); an existing key is kept (renewal), so only the certificate changes.
        Returns the certificate's path."""
        directory.mkdir(parents=True, exist_ok=True)
        key, cert, csr = directory / "key.pem", directory / "cert.pem", directory / "cert.csr"
        if not key.exists():
            _openssl("ecparam", "-name", "prime256v1", "-genkey", "-noout", "-out", str(key))
            key.chmod(0o600)
        _openssl("req", "-new", "-sha256", "-config", str(self._config), "-key", str(key),
                 "-subj", _subj_arg(organization, common_name), "-out", str(csr))
        _openssl("ca", "-batch", "-config", str(self._config), "-days", str(days), "-notext",
                 "-in", str(csr), "-out", str(cert))
        csr.unlink()
        return cert

    def sign(self, document: Path, signed: Path) -> None:
        """S/MIME-sign the XML ``document`` into ``signed`` (what Cyclone verifies)."""
        _openssl("smime", "-sign", "-text", "-in", str(document), "-out", str(signed),
                 "-signer", str(self.cert), "-inkey", str(self.key))

    def revoke(self, cert: Path) -> None:
        """Revoke ``cert`` and write a new revocation list (``crl.pem``)."""
        _openssl("ca", "-config", str(self._config), "-revoke", str(cert))
        self.update_crl()

    def update_crl(self) -> None:
        """Write the revocation list again (it expires after ``crl_days``)."""
        _openssl("ca", "-gencrl", "-config", str(self._config), "-out", str(self.crl))


# -- checks (edge-vis check, edge-vis security show) -----------------------------------------


def certificate_subject(cert: Path) -> str:
    """``cert``'s subject as ``CN=..,O=..`` (raises :class:`PkiError` if not a certificate)."""
    out = _openssl("x509", "-noout", "-subject", "-nameopt", "RFC2253", "-in", str(cert))
    return out.strip().removeprefix("subject=").strip()


def certificate_end(cert: Path) -> str:
    """When ``cert`` expires, as openssl prints it."""
    return _openssl("x509", "-noout", "-enddate", "-in", str(cert)).strip().split("=", 1)[1]


def verify_certificate(ca_cert: Path, cert: Path, crl: Path | None = None) -> None:
    """``cert`` is issued by ``ca_cert``, valid now and (with ``crl``) not revoked."""
    args = ["verify", "-CAfile", str(ca_cert)]
    if crl is not None:
        args += ["-crl_check", "-CRLfile", str(crl)]
    _openssl(*args, str(cert))


def check_private_key(key: Path, cert: Path) -> None:
    """``key`` parses and is the key of ``cert``."""
    public = _openssl("pkey", "-in", str(key), "-pubout")
    if public != _openssl("x509", "-in", str(cert), "-noout", "-pubkey"):
        raise PkiError(f"{key} is not the private key of {cert}")


def verify_document(ca_cert: Path, signed: Path) -> str:
    """The XML text of the S/MIME document ``signed``, if ``ca_cert`` signed it."""
    text = _openssl("smime", "-verify", "-text", "-in", str(signed), "-CAfile", str(ca_cert),
                    "-purpose", "any")
    return text


__all__ = [
    "CA_CERT",
    "CRL",
    "CertificateAuthority",
    "PkiError",
    "certificate_end",
    "certificate_subject",
    "check_private_key",
    "subject_dn",
    "verify_certificate",
    "verify_document",
]
