"""The asyncio shell: the only place where sockets, the clock and Cyclone DDS meet the core.

``relay`` wires links, the router, the engine and the DDS bridge into one running relay;
``service`` is the systemd side (notify, watchdog, supervision), ``reload`` applies a
changed profile, ``mirror`` copies JAUS traffic for Wireshark, ``memory`` tunes the
allocator for a process that runs for days.
"""
