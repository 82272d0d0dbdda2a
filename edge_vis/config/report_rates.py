"""Report rates of a profile's ``[report_rates]`` table (deployment or vehicle). No I/O.

Each report is ``Report = 5.0`` (Hz) or ``Report = {desired = 5.0, minimum = 1.0,
priority = 7}``: the rate wanted when the link allows, the least that is still useful when
the bandwidth planner must degrade it, and how late it is degraded (higher = later).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import ClassVar

from edge_vis.schema import setting

#: minimum useful rate of a report without one in the profile, as a share of its rate
DEFAULT_MINIMUM_SHARE = 0.1
#: planning priority of a report without one in the profile
DEFAULT_REPORT_PRIORITY = 5


@dataclass(frozen=True, slots=True)
class ReportRate:
    """One entry of ``[report_rates]``; a bare number is its ``desired`` rate."""

    toml_shorthand: ClassVar[str] = "desired"

    desired: float = setting(gt=0, unit="Hz", doc="the rate (Hz) wanted when the link allows")
    minimum: float | None = setting(None, gt=0, unit="Hz")
    priority: int | None = setting(None, ge=0, le=9)

    def validate(self) -> Iterator[tuple[str, str]]:
        """A minimum above the desired rate would make the planner raise it."""
        if self.minimum is not None and self.minimum > self.desired:
            yield "minimum", f"{self.minimum:g} Hz is above the desired {self.desired:g} Hz"


#: how ``[report_rates]`` is read
REPORT_RATES = Mapping[str, ReportRate]


def split_rates(rates: Mapping[str, ReportRate]
                ) -> tuple[dict[str, float], dict[str, float], dict[str, int]]:
    """(desired rates, minimum rates, priorities) by report, as the profiles keep them."""
    return ({name: r.desired for name, r in rates.items()},
            {name: r.minimum for name, r in rates.items() if r.minimum is not None},
            {name: r.priority for name, r in rates.items() if r.priority is not None})
