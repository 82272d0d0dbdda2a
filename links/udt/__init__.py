"""The UDT bulk channel: whole, verified, resumable image files from vehicles to operators.

Entry point ``udt`` in group ``edge_vis.bulk`` names :class:`UdtBulkChannel`, a
:class:`~edge_vis.routing.bulk.BulkChannel`. Unlike the JAUS packet links, this plugin
carries files, not packets: large ATR images travel on their
own UDT connection (vehicle → relay → operator station) so they never compete with
control traffic beyond the rate budget they are given.

Modules: :mod:`.protocol` (sans-I/O frames and state machines), :mod:`.spool` (journalled
store-and-forward on disk), :mod:`.link` (udt4py sockets and threads), :mod:`.products`
(bus sample shapes), :mod:`.service` (what the CLI commands run). Importing this package
does not import udt4py; opening a socket without it raises ``LinkError``.
"""

from __future__ import annotations

from typing import ClassVar

from edge_vis.routing.bulk import BulkChannel
from links.udt.fetch_queue import FetchQueue, Wanted
from links.udt.image_server import ImageServer
from links.udt.image_service import ImageService, manifest_for_file, send_image
from links.udt.keys import load_keys
from links.udt.protocol import AtrMetadata, Backoff, Manifest, Position, Reason
from links.udt.spool import Spool, SpoolRefusal
from links.udt.transfer import BulkReceiver, BulkSender, Forwarder, TransferResult, parse_address


class UdtBulkChannel(BulkChannel):
    """The UDT bulk channel, as loaded through the ``edge_vis.bulk`` entry point.

    The core reaches everything through this class so it never imports ``links``::

        udt = edge_vis.plugins.load("edge_vis.bulk", "udt")
        result = udt.send_image("img.png", "10.0.0.2:9000", vehicle_id="uuv1")
        service = udt.ImageService("images/", "0.0.0.0:9000", forward=["ops:9000"]).start()
    """

    scheme: ClassVar[str] = "udt"

    send_image = staticmethod(send_image)
    manifest_for_file = staticmethod(manifest_for_file)
    parse_address = staticmethod(parse_address)
    load_keys = staticmethod(load_keys)
    ImageService = ImageService
    ImageServer = ImageServer
    FetchQueue = FetchQueue
    Wanted = Wanted
    BulkSender = BulkSender
    BulkReceiver = BulkReceiver
    Forwarder = Forwarder
    Spool = Spool
    SpoolRefusal = SpoolRefusal
    Manifest = Manifest
    AtrMetadata = AtrMetadata
    Position = Position
    Backoff = Backoff
    Reason = Reason
    TransferResult = TransferResult


__all__ = ["UdtBulkChannel"]
