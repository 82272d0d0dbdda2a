"""Bandwidth-aware event rates and link scheduling. No I/O except reading link profiles.

* :mod:`~edge_vis.bandwidth.linkspec` - radio link profiles (TOML) and their validation;
* :mod:`~edge_vis.bandwidth.sizes` - bytes on a link per message, from the catalogue;
* :mod:`~edge_vis.bandwidth.planner` - the pure rate planner;
* :mod:`~edge_vis.bandwidth.demands` - what the relay's vehicles want, as planner input;
* :mod:`~edge_vis.routing.traffic` - traffic classes and latest-wins keys for the
  router's per-link queues.

This package must not import :mod:`edge_vis.config` at import time (config imports it).
"""
