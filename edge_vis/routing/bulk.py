"""The bulk-channel contract: plugins that move whole files, not JAUS packets. No I/O.

A JAUS link (:class:`edge_vis.routing.link.Link`) carries packets the router relays; a bulk
channel carries large files (ATR images) on a connection of its own, beside the JAUS
links, so they never compete with control traffic beyond the rate they are given. The two
contracts differ, so they are two entry-point groups: ``edge_vis.links`` for links,
``edge_vis.bulk`` for bulk channels; a plugin in the wrong group fails its type check
instead of failing later inside the relay.

A bulk channel is a class used as a namespace: the core reaches every part through it
(``plugins.load("edge_vis.bulk", "udt").ImageService(...)``) and never imports the
plugin package. Subclasses must provide every name in :data:`REQUIRED`; a missing one
is refused when the class is defined.
"""

from __future__ import annotations

from typing import Any, ClassVar

#: what the relay and the ``send-image`` / ``receive-images`` commands use
REQUIRED: tuple[str, ...] = (
    "scheme", "send_image", "manifest_for_file", "parse_address", "load_keys",
    "ImageService", "BulkSender", "AtrMetadata", "Position",
)


class BulkChannel:
    """Base class of bulk-channel plugins (entry-point group ``edge_vis.bulk``).

    * ``scheme`` - the URL scheme of the channel's addresses (``udt``);
    * ``send_image(path, address, **options)`` - push one file, returning a result;
    * ``ImageService(directory, listen, ...)`` - receive, spool, verify, publish, forward;
    * ``BulkSender`` - a sending connection; ``AtrMetadata``/``Position`` - what a file
      carries about its target; ``manifest_for_file``, ``parse_address``, ``load_keys``.
    """

    scheme: ClassVar[str] = ""
    send_image: ClassVar[Any]
    manifest_for_file: ClassVar[Any]
    parse_address: ClassVar[Any]
    load_keys: ClassVar[Any]
    ImageService: ClassVar[Any]
    BulkSender: ClassVar[Any]
    AtrMetadata: ClassVar[Any]
    Position: ClassVar[Any]

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        missing = [name for name in REQUIRED if not getattr(cls, name, None)]
        if missing:
            raise TypeError(f"bulk channel {cls.__qualname__} lacks {', '.join(missing)}")
