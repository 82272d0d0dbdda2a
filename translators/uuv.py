"""The ``uuv`` translator: ocean data and ATR image notices of the shipped ``uuv`` set. No I/O.

Everything else of the shipped UUV support is data: the message set is JSIDL
(``edge_vis/data/jsidl/uuv/``) and a UUV is discovered from its ``VendorHello`` by a
vehicle profile (``profiles/vehicles/uuv.toml``, ``[discovery] hello``). This translator
stays, written against the public plugin API only, as the example of what a profile
mapping cannot say: samples of the shipped typed topics with computed fields.

* ReportOceanEnvironment -> ``EnvironmentalData`` (deg C, PSU, m, m/s, rad; a field not
  reported is NaN, never 0).
* ReportAtrImageAvailable -> ``ImageProduct`` announcing the ATR image: an image id and
  file name made of the message's fields, the format's label, the SHA-256 as hex and a
  target list built from four fields; the bulk image channel fetches the image and checks
  it against the SHA-256.

Deleting ``"uuv"`` from the profile's ``[translators] enabled`` list (or adding it to
``disabled``) removes it and leaves every other translator working.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from edge_vis.kit import (
    NAN,
    Computed,
    Const,
    From,
    ReportRule,
    RuleTranslator,
)

UUV = "urn:edge-vis:uuv:"
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


class UuvTranslator(RuleTranslator):
    """The ``uuv`` message set -> EnvironmentalData, ImageProduct."""

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


def _format(f: Mapping[str, Any]) -> str:
    return IMAGE_FORMATS.get(int(f.get("format", -1)), "bin")
