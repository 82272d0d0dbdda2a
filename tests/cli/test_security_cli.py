"""``edge-vis security``, ``edge-vis check`` and ``edge-vis run`` with ``[dds.security]``:
the deployment PKI made with the real ``openssl`` command, checked as a deployer would.

What the secured participants then do on a DDS domain is tests/dds/test_dds_security.py.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from edge_vis.cli import main as cli

pytestmark = pytest.mark.skipif(shutil.which("openssl") is None,
                                reason="the openssl command is not installed")

PROFILE = """
[relay]
jaus_id = "200.1.1"
name = "relay1"
[dds]
domain = 12
partitions = ["site-a"]
[translators]
enabled = ["core", "mobility"]
[[operators]]
id = "op1"
[[operators]]
id = "op2"
max_authority = 50
"""

TABLE = """
[dds.security]
identity_ca = "security/ca/ca.pem"
certificate = "security/relay/relay1/cert.pem"
private_key = "security/relay/relay1/key.pem"
permissions_ca = "security/ca/ca.pem"
governance = "security/governance.p7s"
permissions = "security/relay/relay1/permissions.p7s"
crl = "security/ca/crl.pem"
"""


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A deployment: profile, ``security/`` from ``init``, and a foreign one (another CA)."""
    root = tmp_path_factory.mktemp("pki")
    (root / "relay.toml").write_text(PROFILE)
    for name in ("security", "foreign"):
        assert cli(["security", "init", "--profile", str(root / "relay.toml"), "--dir",
                    str(root / name), "--observer", "wall"]) == 0
    (root / "relay.toml").write_text(PROFILE + TABLE)
    return root


@pytest.fixture
def site(made: Path, tmp_path: Path) -> Path:
    """A copy of the deployment this test may change."""
    shutil.copytree(made, tmp_path / "site")
    return tmp_path / "site"


def _openssl(*args: str) -> str:
    return subprocess.run(["openssl", *args], capture_output=True, text=True,
                          check=True).stdout


def test_init_prints_the_profile_table_and_issues_every_identity(
        made: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "relay.toml").write_text(PROFILE)
    assert cli(["security", "init", "--profile", str(tmp_path / "relay.toml"), "--dir",
                str(tmp_path / "security")]) == 0
    out = capsys.readouterr().out
    assert TABLE.strip() in out  # paste it into the profile as printed
    for who in ("relay/relay1", "operator/op1", "operator/op2"):
        cert = tmp_path / "security" / who / "cert.pem"
        _openssl("verify", "-CAfile", str(tmp_path / "security/ca/ca.pem"), str(cert))
        assert f"CN={who.replace('/', '.')}" in _openssl("x509", "-noout", "-subject", "-nameopt",
                                                         "RFC2253", "-in", str(cert))
    assert (tmp_path / "security/operator/op1/cyclonedds.xml").read_text().count("file:/") == 6


def test_each_operator_may_write_commands_only_in_its_own_partition(made: Path) -> None:
    ca = made / "security/ca/ca.pem"
    text = _openssl("smime", "-verify", "-text", "-CAfile", str(ca), "-purpose", "any",
                    "-in", str(made / "security/operator/op2/permissions.p7s"))
    publish = text.split("<publish>")[1].split("</publish>")[0]
    assert "<topic>ControlRequest</topic>" in publish
    assert "<topic>WrenchEffortCommand</topic>" in publish
    assert "<topic>GlobalPose</topic>" not in publish  # vehicle topics: relays only
    assert "<partition>operator.op2</partition>" in publish
    assert "operator.op1" not in text
    subscribe = text.split("<subscribe>")[1].split("</subscribe>")[0]
    assert "<partition>site-a</partition>" in subscribe
    observer = _openssl("smime", "-verify", "-text", "-CAfile", str(ca), "-purpose", "any",
                        "-in", str(made / "security/observer/wall/permissions.p7s"))
    assert "<publish>" not in observer
    governance = _openssl("smime", "-verify", "-text", "-CAfile", str(ca), "-purpose", "any",
                          "-in", str(made / "security/governance.p7s"))
    assert "<allow_unauthenticated_participants>false<" in governance
    assert "<data_protection_kind>ENCRYPT<" in governance


def test_check_accepts_the_secured_profile(made: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    assert cli(["check", str(made / "relay.toml")]) == 0
    assert "DDS Security" in capsys.readouterr().out


@pytest.mark.parametrize(("change", "key", "words"), [
    ("missing", "dds.security.permissions", "no such file"),
    ("foreign permissions", "dds.security.permissions", "not signed by the permissions CA"),
    ("foreign certificate", "dds.security.certificate", "not valid under the identity CA"),
    ("other operator's permissions", "dds.security.permissions",
     "grants nothing to the certificate's subject CN=relay.relay1"),
    ("open access", "access.any_operator", "set it to false"),
    ("another domain", "dds.security.governance",
     "has no rule for the profile's DDS domain 13"),
    ("another partition", "dds.security.permissions",
     "do not let the relay publish in the profile's partition(s) site-b"),
    ("corrupt certificate", "dds.security.certificate",
     "`openssl x509 -noout -subject -nameopt RFC2253 -in "),
])
def test_check_refuses_material_not_signed_by_the_configured_ca(
        site: Path, change: str, key: str, words: str,
        capsys: pytest.CaptureFixture[str]) -> None:
    ours = site / "security/relay/relay1"
    if change == "missing":
        (ours / "permissions.p7s").unlink()
    elif change == "foreign permissions":
        shutil.copy(site / "foreign/relay/relay1/permissions.p7s", ours / "permissions.p7s")
    elif change == "foreign certificate":
        shutil.copy(site / "foreign/relay/relay1/cert.pem", ours / "cert.pem")
        shutil.copy(site / "foreign/relay/relay1/key.pem", ours / "key.pem")
    elif change == "other operator's permissions":
        shutil.copy(site / "security/operator/op1/permissions.p7s", ours / "permissions.p7s")
    elif change == "another domain":  # the profile moved, the documents did not
        profile = site / "relay.toml"
        profile.write_text(profile.read_text().replace("domain = 12", "domain = 13"))
    elif change == "another partition":
        profile = site / "relay.toml"
        profile.write_text(profile.read_text().replace('"site-a"', '"site-a", "site-b"'))
    elif change == "corrupt certificate":  # openssl's own words reach the deployer
        (ours / "cert.pem").write_text("not a certificate\n")
        words += f"{ours / 'cert.pem'}` failed (exit 1): Could not read certificate from"
    else:
        profile = site / "relay.toml"
        profile.write_text(profile.read_text() + "[access]\nany_operator = true\n")
    assert cli(["check", str(site / "relay.toml")]) == 2
    err = capsys.readouterr().err
    assert key in err and words in err, err


def test_a_revoked_relay_certificate_fails_the_check(site: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    assert cli(["security", "revoke", "--dir", str(site / "security"), "relay1"]) == 0
    assert cli(["check", str(site / "relay.toml")]) == 2
    assert "certificate revoked" in capsys.readouterr().err
    assert cli(["security", "show", "--dir", str(site / "security")]) == 2
    lines = capsys.readouterr().out.splitlines()
    assert any("relay1" in line and "revoked" in line for line in lines)
    assert any("op1" in line and line.endswith("ok") for line in lines)


def test_renew_keeps_the_keys_and_issues_new_certificates(site: Path) -> None:
    cert = site / "security/operator/op1/cert.pem"
    key = (site / "security/operator/op1/key.pem").read_bytes()
    serial = _openssl("x509", "-noout", "-serial", "-in", str(cert))
    assert cli(["security", "renew", "--profile", str(site / "relay.toml"), "--dir",
                str(site / "security"), "--days", "30"]) == 0
    assert _openssl("x509", "-noout", "-serial", "-in", str(cert)) != serial
    assert (site / "security/operator/op1/key.pem").read_bytes() == key
    assert cli(["check", str(site / "relay.toml")]) == 0


def test_init_again_after_adding_an_operator_keeps_the_ca_and_others(site: Path) -> None:
    ca = (site / "security/ca/ca.pem").read_bytes()
    op1 = (site / "security/operator/op1/cert.pem").read_bytes()
    profile = site / "relay.toml"
    profile.write_text(profile.read_text() + '[[operators]]\nid = "op3"\n')
    assert cli(["security", "init", "--profile", str(profile), "--dir",
                str(site / "security")]) == 0
    assert (site / "security/ca/ca.pem").read_bytes() == ca
    assert (site / "security/operator/op1/cert.pem").read_bytes() == op1
    assert (site / "security/operator/op3/permissions.p7s").is_file()


def test_a_bad_operator_id_for_a_partition_is_refused(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "relay.toml").write_text(PROFILE.replace('"op2"', '"op/2"'))
    assert cli(["security", "init", "--profile", str(tmp_path / "relay.toml"), "--dir",
                str(tmp_path / "security")]) == 2
    assert "'op/2': a name for DDS Security must be" in capsys.readouterr().err


@pytest.mark.parametrize("half", ["missing file", "security only in CYCLONEDDS_URI",
                                  "binding without DDS Security", "--domain elsewhere"])
def test_run_refuses_to_start_half_secured(site: Path, half: str,
                                           monkeypatch: pytest.MonkeyPatch,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    profile = site / "relay.toml"
    if half == "missing file":
        (site / "security/governance.p7s").unlink()
        expected = "dds.security.governance"
    elif half == "security only in CYCLONEDDS_URI":
        profile.write_text(PROFILE)
        xml = site / "security/operator/op1/cyclonedds.xml"
        monkeypatch.setenv("CYCLONEDDS_URI", f"file://{xml}")
        expected = "CYCLONEDDS_URI turns DDS Security on"
    elif half == "--domain elsewhere":  # refused before joining, on either binding
        expected = "dds.security.permissions: allow nothing in the profile's DDS domain 14"
    else:
        secure_qos = pytest.importorskip("edge_vis.dds.secure_qos")
        if secure_qos.security_available():
            pytest.skip("this binding has DDS Security")
        expected = "scripts/setup.sh --secure"
    domain = ["--domain", "14"] if half == "--domain elsewhere" else []
    assert cli(["run", "--profile", str(profile), "--duration", "0.1", *domain]) == 2
    err = capsys.readouterr().err
    assert expected in err, err
