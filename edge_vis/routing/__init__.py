"""The node-manager role, sans-I/O: the link contract links implement (``link``), the
router (address book, relay, ACK/NAK, per-link queues; ``router``) and the traffic
policy its queues apply (latest-wins keys, traffic class to priority; ``traffic``)."""
