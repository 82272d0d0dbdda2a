"""A simulated vehicle serves its ATR images over UDT, as ``edge-vis serve-images`` does.

A relay that hears the vehicle announce an image fetches it from here (``[bulk.sources]``).
Uses the ``udt`` bulk plugin; a simulation without udt4py says so when it is asked to serve.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from edge_vis import plugins
from edge_vis.errors import ConfigError
from edge_vis.tools.sim.profile import VehicleSpec


def start_image_server(spec: VehicleSpec) -> Any:
    """Serve ``spec.atr_dir`` on ``spec.image_server``; the started server (``.address``)."""
    if not spec.atr_dir:
        raise ConfigError([("sim profile", f"vehicles ({spec.name}).image_server",
                            "needs atr_dir: the folder whose images it serves")])
    udt = plugins.load(plugins.BULK, "udt")
    try:
        address = udt.parse_address(spec.image_server)
    except ValueError as exc:
        raise ConfigError([("sim profile", f"vehicles ({spec.name}).image_server",
                            str(exc))]) from None
    Path(spec.atr_dir).mkdir(parents=True, exist_ok=True)
    return udt.ImageServer(spec.atr_dir, address, vehicle_id=spec.name).start()
