"""``edge-vis security``: the DDS Security material of a deployment, from its relay profile.

``init`` creates the deployment CA (once), the signed governance document, and for the
relay, each ``[[operators]]`` id and each ``--observer`` a key, a certificate and signed
permissions (see :mod:`edge_vis.tools.access_documents` for what each may do), then
prints the ``[dds.security]`` table for the relay's profile. Run it again after editing
``[[operators]]``: identities that exist are kept, new ones are issued, and every
permissions document is signed again. ``renew`` issues new certificates (same keys) and
permissions valid for ``--days`` more. ``revoke NAME`` revokes an identity's certificate
and rewrites the revocation list ``ca/crl.pem``, which every participant loads. ``show``
lists identities with their subjects, expiry and whether they verify. Needs the
``openssl`` command; nothing is sent anywhere.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from edge_vis.config import load_profile
from edge_vis.tools.access_documents import RELAY
from edge_vis.tools.deployment_keys import SecurityDirectory, security_problems, security_table
from edge_vis.tools.pki import PkiError, certificate_end, certificate_subject, verify_certificate

NAME = "security"
HELP = "create and manage DDS Security: deployment CA, identities, signed permissions"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    for action, text in (("init", "create the CA (once), identities and signed documents"),
                         ("renew", "issue every identity's certificate and permissions again")):
        p = sub.add_parser(action, help=text, description=text)
        p.add_argument("--profile", type=Path, required=True,
                       help="the relay's deployment profile ([[operators]], [dds])")
        p.add_argument("--dir", type=Path, default=Path("security"),
                       help="the security directory (default: ./security)")
        p.add_argument("--org", default="edge-vis deployment",
                       help="organisation name in every subject (default: %(default)s)")
        p.add_argument("--observer", action="append", default=[], metavar="NAME",
                       help="a read-only identity (monitor, display); repeatable")
        p.add_argument("--days", type=int, default=365,
                       help="validity of certificates and permissions (default 365)")
    p = sub.add_parser("revoke", help="revoke an identity's certificate")
    p.add_argument("name", help="identity name, or ROLE/NAME (e.g. operator/op2)")
    p.add_argument("--dir", type=Path, default=Path("security"))
    p = sub.add_parser("show", help="list identities, subjects, expiry; check each")
    p.add_argument("--dir", type=Path, default=Path("security"))


def run(args: argparse.Namespace) -> int:
    directory = SecurityDirectory(args.dir)
    try:
        return int(ACTIONS[args.action](directory, args))
    except PkiError as exc:
        print(f"edge-vis security {args.action}: {exc}", file=sys.stderr)
        return 2


def _issue(directory: SecurityDirectory, args: argparse.Namespace) -> int:
    profile = load_profile(args.profile)
    written = directory.issue_all(profile, args.org, observers=args.observer, days=args.days,
                                  renew=args.action == "renew")
    for ident in written:
        print(f"{ident.role:9} {ident.name:16} {ident.directory}  "
              f"(until {certificate_end(ident.cert)})")
    relay = next(i for i in written if i.role == RELAY)
    print(f"\n# the relay's profile {args.profile}:")
    print(security_table(directory.profile_for(relay), args.profile.parent))
    print("# each operator station: its directory's files, or CYCLONEDDS_URI=file://"
          f"{directory.directory.resolve()}/operator/ID/cyclonedds.xml; commands in the DDS "
          "partition operator.ID")
    return 0


def _revoke(directory: SecurityDirectory, args: argparse.Namespace) -> int:
    ident = directory.find(args.name)
    directory.revoke(ident)
    print(f"revoked {ident.role}/{ident.name}; new revocation list {directory.ca.crl}: "
          "copy it to every relay and station (and remove a revoked operator from "
          "[[operators]])")
    return 0


def _show(directory: SecurityDirectory, args: argparse.Namespace) -> int:
    directory.ca.open()
    print(f"CA {certificate_subject(directory.ca.cert)} until {certificate_end(directory.ca.cert)}")
    status = 0
    for ident in directory.identities():
        try:
            verify_certificate(directory.ca.cert, ident.cert, directory.ca.crl)
            problems = [p for _, p in security_problems(directory.profile_for(ident))]
        except PkiError as exc:
            problems = [str(exc)]
        state = "ok" if not problems else "; ".join(problems)
        status = status or (2 if problems else 0)
        print(f"{ident.role:9} {ident.name:16} {certificate_subject(ident.cert)}  until "
              f"{certificate_end(ident.cert)}  {state}")
    return status


ACTIONS = {"init": _issue, "renew": _issue, "revoke": _revoke, "show": _show}
