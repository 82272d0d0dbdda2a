"""Tools around the relay that are not the relay: the simulated fleet (``sim``), the
operator view (``monitor_view``) and in-process test links (``testing``)."""
