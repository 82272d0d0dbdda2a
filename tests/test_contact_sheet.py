"""The operator's contact sheet: the latest image of each vehicle, thumbnail embedded."""

from __future__ import annotations

import base64
import re

from edge_vis.tools.contact_sheet import ContactSheet
from links.udt.thumbnail import decode, thumbnail


def product(vehicle: str, image: str, capture_ms: int, thumb: bytes = b"", **extra) -> dict:
    return {"vehicle_id": vehicle, "image_id": image, "file_name": f"{image}.pgm",
            "size_bytes": 20480, "sha256": "ab" * 32, "transfer_id": extra.pop("tid", ""),
            "capture_time_ms": capture_ms, "targets": [], "thumbnail_png": list(thumb),
            **extra}


def embedded(page: str) -> list[bytes]:
    return [base64.b64decode(m) for m in re.findall(r'src="data:image/png;base64,([^"]+)"',
                                                    page)]


def test_latest_image_per_vehicle_with_its_thumbnail():
    picture = b"P5 4 4 255\n" + bytes(range(0, 160, 10))
    thumb = thumbnail(picture)
    sheet = ContactSheet()
    assert sheet.ingest(product("uuv1", "atr-1", 1000))                   # announced
    assert "no thumbnail" in sheet.render() and "announced" in sheet.render()
    assert sheet.ingest(product("uuv1", "atr-1", 1000, thumb, tid="t1"))  # verified
    page = sheet.render()
    assert embedded(page) == [thumb] and decode(embedded(page)[0])[:2] == (4, 4)
    assert "verified" in page
    # a later sample of the same image without the thumbnail keeps it
    sheet.ingest(product("uuv1", "atr-1", 1000, tid="t1"))
    assert embedded(sheet.render()) == [thumb]
    # a newer image replaces it, an older one arriving late does not
    assert sheet.ingest(product("uuv1", "atr-3", 3000))
    assert not sheet.ingest(product("uuv1", "atr-2", 2000, thumb))
    assert "atr-3.pgm" in sheet.render() and "atr-2" not in sheet.render()
    sheet.ingest(product("uuv2", "atr-9", 500, thumb, targets=[
        {"target_class": "mine-like", "confidence": 0.87}]))
    page = sheet.render()
    assert page.index("uuv1") < page.index("uuv2") and "mine-like 87%" in page


def test_names_are_escaped():
    sheet = ContactSheet()
    sheet.ingest(product("<b>uuv", "x", 1, file_name="<script>.png"))
    page = sheet.render()
    assert "<script>" not in page and "&lt;script&gt;.png" in page
