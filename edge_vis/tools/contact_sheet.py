"""The latest image of each vehicle as one HTML page a browser opens. Pure: samples in, text out.

``edge-vis monitor --contact-sheet FILE`` feeds every ``ImageProduct`` it reads here and
rewrites FILE when the page changes. The thumbnails travel inside the product
(``thumbnail_png``), so the page needs nothing but the DDS samples: it embeds them as
``data:`` URIs and works from any machine on the operator's domain. An image whose format
gets no thumbnail is listed with its name, size and hash only.
"""

from __future__ import annotations

import base64
import html
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any


@dataclass
class ContactSheet:
    """Latest ``ImageProduct`` per vehicle (by capture time, then arrival)."""

    title: str = "edge-vis: latest image per vehicle"
    latest: dict[str, dict[str, Any]] = field(default_factory=dict)
    _arrival: int = 0

    def ingest(self, sample: Mapping[str, Any]) -> bool:
        """Take one ``ImageProduct`` sample; True if the page changed."""
        vehicle = str(sample.get("vehicle_id", ""))
        if not vehicle:
            return False
        self._arrival += 1
        new = {**sample, "_arrival": self._arrival}
        old = self.latest.get(vehicle)
        if old is not None and old.get("image_id") != sample.get("image_id") and (
                int(old.get("capture_time_ms", 0) or 0)
                > int(sample.get("capture_time_ms", 0) or 0)):
            return False  # an older image arriving late does not replace the latest
        if old is not None and old.get("image_id") == sample.get("image_id") \
                and not _thumb(sample) and _thumb(old):
            new["thumbnail_png"] = old["thumbnail_png"]  # keep what the transfer added
        self.latest[vehicle] = new
        return True

    def render(self, now: float | None = None) -> str:
        """The page: one card per vehicle, sorted by vehicle id."""
        stamp = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(now))
        cards = "\n".join(_card(self.latest[v]) for v in sorted(self.latest))
        return (
            "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\">"
            "<meta http-equiv=\"refresh\" content=\"5\">"
            f"<title>{html.escape(self.title)}</title><style>"
            "body{font-family:sans-serif;background:#111;color:#ddd}"
            ".card{display:inline-block;vertical-align:top;margin:8px;padding:8px;"
            "background:#222;border-radius:6px;width:220px}"
            ".card img{width:192px;image-rendering:pixelated;background:#000}"
            ".none{width:192px;height:144px;display:flex;align-items:center;"
            "justify-content:center;background:#000;color:#777}"
            "small{color:#999}</style></head><body>"
            f"<h1>{html.escape(self.title)}</h1><p><small>written {stamp}; the page "
            "reloads every 5 s</small></p>\n"
            f"{cards or '<p>no images yet</p>'}\n</body></html>\n"
        )


def _thumb(sample: Mapping[str, Any]) -> bytes:
    value = sample.get("thumbnail_png") or b""
    return bytes(value)


def _card(s: Mapping[str, Any]) -> str:
    e = html.escape
    thumb = _thumb(s)
    picture = (f"<img alt=\"{e(str(s.get('file_name', '')))}\" src=\"data:image/png;base64,"
               f"{base64.b64encode(thumb).decode('ascii')}\">" if thumb else
               "<div class=\"none\">no thumbnail</div>")
    targets = ", ".join(f"{e(str(t.get('target_class', '?')))} "
                        f"{float(t.get('confidence', 0.0)):.0%}"
                        for t in s.get("targets") or [])
    when = int(s.get("capture_time_ms", 0) or 0)
    captured = time.strftime("%H:%M:%S", time.gmtime(when / 1000)) if when else "?"
    state = "fetched and verified" if s.get("transfer_id") else "announced over JAUS"
    return (
        f"<div class=\"card\"><b>{e(str(s.get('vehicle_id', '')))}</b><br>{picture}<br>"
        f"{e(str(s.get('file_name', '') or s.get('image_id', '')))}<br>"
        f"<small>{int(s.get('size_bytes', 0) or 0) // 1024} KiB, captured {captured}, "
        f"{state}<br>sha256 {e(str(s.get('sha256', ''))[:16])}...</small>"
        + (f"<br>ATR: {targets}" if targets else "") + "</div>"
    )
