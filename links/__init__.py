"""Link-layer plugins (entry-point group ``edge_vis.links``): JUDP over UDP, serial, UDT."""
