"""JAUS TimeRec <-> seconds since the epoch, checked against the datetime module."""

from __future__ import annotations

import datetime as dt
import random

import pytest

from edge_vis.engine.clocks import epoch_of, time_fields


def _datetime(fields: dict) -> dt.datetime:
    s, d = fields["time_stamp"], fields["date_stamp"]
    return dt.datetime(2000 + d["year"], d["month"], s["day"], s["hour"], s["minutes"],
                       s["seconds"], s["milliseconds"] * 1000, tzinfo=dt.UTC)


@pytest.mark.parametrize("seed", range(5))
def test_time_fields_name_the_same_instant_as_datetime(seed: int) -> None:
    rng = random.Random(seed)
    for _ in range(200):  # 2000-01-01 .. 2127, leap days and month ends included
        epoch = rng.uniform(946_684_800, 4_354_819_199)
        epoch = round(epoch * 1000) / 1000
        fields = time_fields(epoch)
        assert _datetime(fields).timestamp() == pytest.approx(epoch, abs=1e-6)
        assert epoch_of(fields, 0.0) == pytest.approx(epoch, abs=1e-6)


def test_a_leap_day_and_a_year_end() -> None:
    leap = dt.datetime(2024, 2, 29, 23, 59, 59, 999000, tzinfo=dt.UTC).timestamp()
    assert time_fields(leap)["date_stamp"] == {"day": 29, "month": 2, "year": 24}
    end = dt.datetime(2030, 12, 31, 12, 0, tzinfo=dt.UTC).timestamp()
    assert epoch_of(time_fields(end), 0.0) == end


def test_a_report_without_date_takes_the_relays_month() -> None:
    near = dt.datetime(2026, 11, 24, 2, 0, tzinfo=dt.UTC).timestamp()
    fields = time_fields(near + 5.25)
    del fields["date_stamp"]
    assert epoch_of(fields, near) == pytest.approx(near + 5.25)


def test_unusable_reports_give_none() -> None:
    assert epoch_of({}, 0.0) is None
    assert epoch_of({"time_stamp": {"day": 0, "hour": 1}}, 0.0) is None
    assert epoch_of({"time_stamp": {"day": 3}, "date_stamp": {"month": 13, "year": 1}},
                    0.0) is None
