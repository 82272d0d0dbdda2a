"""Which components the relay asks who holds them."""

from __future__ import annotations

from edge_vis.engine.discovery import with_inherited


def test_iop_enhanced_access_control_is_asked_like_access_control() -> None:
    # jsidl-iop EnhancedAccessControl inherits_from urn:jaus:jss:core:AccessControl 1.1
    uris = {u for u, _v in with_inherited([("urn:jaus:jss:iop:EnhancedAccessControl", "1.1")])}
    assert "urn:jaus:jss:core:AccessControl" in uris
    assert "urn:jaus:jss:core:Events" in uris
