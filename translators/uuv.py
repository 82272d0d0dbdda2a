"""The ``uuv`` translator: a custom underwater vehicle (message set ``uuv``). No I/O.

An example of a vendor translator written against the public plugin API only; deleting
``"uuv"`` from the profile's ``[translators] enabled`` list (or adding it to ``disabled``)
removes it and leaves every other translator working.

* Discovery: ``VendorHello`` (broadcast by vehicles without JAUS Discovery) ->
  :class:`~edge_vis.kit.actions.DeclareVehicle` with the vehicle's name, type, JAUS ID
  and services. A vehicle that sends nothing at all is described in a static vehicle
  profile instead (``components`` with their services); the engine declares it at start-up.
* ReportOceanEnvironment -> ``EnvironmentalData`` (deg C, PSU, m, m/s, rad).
* ReportAtrImageAvailable -> ``ImageProduct`` announcing the ATR image (with its target)
  that the bulk image channel fetches and checks against the SHA-256.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from edge_vis.kit import (
    NAN,
    Action,
    Computed,
    Const,
    DeclareVehicle,
    From,
    JausAddress,
    ReportRule,
    RuleTranslator,
    TranslatorContext,
    derive_vehicle_id,
    describe_rules,
    label,
)

UUV = "urn:edge-vis:uuv:"
VEHICLE_TYPES = {0: "UNKNOWN", 1: "AUV", 2: "ROV", 3: "GLIDER", 4: "USV", 5: "HYBRID"}
IMAGE_FORMATS = {0: "jpeg", 1: "png", 2: "tiff", 3: "geotiff", 4: "raw_sonar", 5: "xtf",
                 6: "raw_camera"}
INT64_MAX = (1 << 63) - 1
ENVIRONMENT_FIELDS = ("water_temperature", "salinity", "depth", "current_speed",
                      "current_direction")


def _image_id(f: Mapping[str, Any]) -> str:
    return f"atr-{int(f.get('image_id', 0))}"


def _ms(value: object) -> int:
    """A u64 millisecond time as DDS int64 (a value past year 292 million saturates)."""
    return min(int(value), INT64_MAX)  # type: ignore[call-overload]


def _targets(f: Mapping[str, Any]) -> list[dict[str, Any]]:
    if not f.get("target_class"):
        return []
    return [{"target_class": str(f["target_class"]),
             "confidence": float(f.get("confidence", NAN)),
             "latitude": float(f.get("latitude", NAN)),
             "longitude": float(f.get("longitude", NAN)),
             "depth": NAN}]


def _services(f: Mapping[str, Any]) -> tuple[tuple[str, str], ...]:
    return tuple((str(s["uri"]), f"{int(s['major_version'])}.{int(s['minor_version'])}")
                 for s in f.get("services") or ())


def hello_declaration(fields: Mapping[str, Any]) -> DeclareVehicle | None:
    """The vehicle a VendorHello describes (None when its JAUS ID is unusable)."""
    jid = fields.get("jaus_id") or {}
    try:
        address = JausAddress(int(jid["subsystem"]), int(jid["node"]), int(jid["component"]))
    except (KeyError, TypeError, ValueError):
        return None
    if address.is_broadcast or 0 in (address.subsystem, address.node, address.component):
        return None
    name = str(fields.get("vehicle_name", "") or "")
    kind = label(VEHICLE_TYPES)(fields.get("vehicle_type", 0))
    return DeclareVehicle(derive_vehicle_id(name, address.subsystem),
                          {address: _services(fields)}, name=name, vehicle_type=kind)


class UuvTranslator(RuleTranslator):
    """The ``uuv`` message set -> vehicle declaration, EnvironmentalData, ImageProduct."""

    name = "uuv"
    report_rules = (
        ReportRule("ReportOceanEnvironment", "EnvironmentalData",
                   {name: From(name) for name in ENVIRONMENT_FIELDS},
                   query="QueryOceanEnvironment", service=UUV + "OceanEnvironmentSensor",
                   query_fields={"presence_vector": 0x3F}, rate=1.0),
        ReportRule("ReportAtrImageAvailable", "ImageProduct",
                   {"image_id": Computed(_image_id, "atr-<image_id>"),
                    "file_name": Computed(lambda f: f"{_image_id(f)}.{_format(f)}",
                                          "atr-<image_id>.<format>"),
                    "size_bytes": From("size_bytes"),
                    "sha256": From("sha256", convert=lambda b: bytes(b).hex(), default=""),
                    "transfer_id": Const("", "set when the bulk channel fetches it"),
                    "format": Computed(lambda f: _format(f), "format"),
                    "capture_time_ms": From("capture_time", default=0, convert=_ms,
                                            note="ms since epoch"),
                    "targets": Computed(_targets,
                                        "target_class, confidence, latitude, longitude")},
                   stamp=False, doc="announces the image; the bulk channel fetches it"),
    )
    extra_messages = ("VendorHello",)

    def on_message(
        self, name: str, fields: Mapping[str, Any], ctx: TranslatorContext
    ) -> list[Action]:
        if name == "VendorHello":
            declaration = hello_declaration(fields)
            return [declaration] if declaration is not None else []
        return super().on_message(name, fields, ctx)

    def describe(self) -> list[dict[str, Any]]:
        hello = ReportRule("VendorHello", "(vehicle declaration)",
                           {"vehicle_id": Computed(lambda f: "", "vehicle_name-subsystem"),
                            "name": From("vehicle_name"),
                            "vehicle_type": From("vehicle_type"),
                            "components": Computed(lambda f: "", "jaus_id -> services[]")},
                           doc="DeclareVehicle: discovery without QueryIdentification; "
                               "VehicleIdentification follows from the core translator")
        return describe_rules(self.name, (hello,), ()) + super().describe()


def _format(f: Mapping[str, Any]) -> str:
    return IMAGE_FORMATS.get(int(f.get("format", -1)), "bin")
