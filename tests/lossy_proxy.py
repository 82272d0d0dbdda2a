"""The emulated radio of tests and benches (:mod:`edge_vis.tools.lossy_udp`)."""

from edge_vis.tools.lossy_udp import LossyProxy, separate_process

__all__ = ["LossyProxy", "separate_process"]
