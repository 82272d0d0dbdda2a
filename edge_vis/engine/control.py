"""JAUS access control and management of one remote component. No I/O, explicit ``now``.

Theory of operation
-------------------
The relay is *one* JAUS client. While an operator holds a vehicle, the engine sets
``wanted`` on each component it must command; this machine then keeps control of that
component with the relay's authority, and brings it to READY before commands flow.

Rule 1: control is kept alive by re-sending RequestControl before the component's timeout
(AS5710 AccessControl). The timeout is asked once with QueryTimeout; renewal happens at
half of it. A component that never answers (the JTS example) is renewed every
``renewal_period``. A reported timeout of 0 means "never times out": no renewal.

Rule 2: a component with the Management service must be READY before commanding: while it
is not, the relay sends Resume and QueryStatus at most ``max_ready_attempts`` times, then
proceeds anyway and records a note (the JTS example reports INITIALIZE forever). EMERGENCY
and FAILURE are never "ready": motion commands wait. A component leaving EMERGENCY (its
emergency cleared) is driven to READY again with fresh attempts; while in EMERGENCY it
answers RequestControl with NOT_AVAILABLE yet keeps its controller, so that answer does
not end control.

Rule 2a: an operator's Standby holds: after the relay sent Standby on an operator's
behalf it does not drive the component back to READY until the operator sends Resume
(or releases the vehicle). Control held only for the relay's own errands (SetTime,
``errand``) never drives readiness either.

Rule 2b: the relay's authority may change while it holds control (it follows the
operator's, ``control.authority_from_operator``): lower goes out as SetAuthority, higher
as RequestControl, the two ways AccessControl lets the controlling client change it.

Rule 3: when ``wanted`` drops (last operator released, relay stopping), the relay sends
ReleaseControl; RejectControl(CONTROL_RELEASED), or a timeout, ends it.

Transitions (``state``, input) -> (new state, output):

=============  =============================  ==============  ==============================
state          input                          new state       output
=============  =============================  ==============  ==============================
IDLE           wanted                         REQUESTING      RequestControl
REQUESTING     ConfirmControl(0)              CONTROLLED      QueryTimeout (first time)
REQUESTING     ConfirmControl(1, 2)           REFUSED         -
REQUESTING     no answer (response_timeout)   REQUESTING      RequestControl (again)
REFUSED        retry_period elapsed           REQUESTING      RequestControl
CONTROLLED     renewal due                    CONTROLLED      RequestControl
CONTROLLED     RejectControl                  REQUESTING      RequestControl (after retry)
any            not wanted                     RELEASING/IDLE  ReleaseControl if we held it
RELEASING      RejectControl / timeout        IDLE            -
any            vehicle lost                   IDLE            - (re-requested when found)
=============  =============================  ==============  ==============================
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from edge_vis.config import ControlProfile

# Management status codes (ReportStatus.status).
INITIALIZE, READY, STANDBY, SHUTDOWN, FAILURE, EMERGENCY = range(6)
NOT_OPERATIONAL = frozenset({FAILURE, EMERGENCY, SHUTDOWN})


class ControlState(enum.Enum):
    """Where the relay stands with one component's access control."""

    IDLE = "idle"
    REQUESTING = "requesting"
    CONTROLLED = "controlled"
    REFUSED = "refused"
    RELEASING = "releasing"


@dataclass(frozen=True, slots=True)
class Outgoing:
    """A message this machine wants sent to its component."""

    name: str
    fields: Mapping[str, Any]


class ComponentControl:
    """Access control + management readiness of one component (see module docstring)."""

    def __init__(self, profile: ControlProfile, authority: int, managed: bool) -> None:
        self.profile = profile
        self.authority = authority
        self.managed = managed
        self.wanted = False
        self.state = ControlState.IDLE
        self.deadline: float | None = None
        self.timeout: float | None = None  # seconds, from ReportTimeout
        self.timeout_asked = False
        self.status: int | None = None
        self.ready_attempts = 0
        self.ready_deadline: float | None = None
        self.note = ""
        self.last_response = 0
        self.request_attempts = 0
        #: a ReleaseControl that timed out
        self.unanswered = False
        #: an operator's Standby is in force: do not drive READY (rule 2a)
        self.hold_standby = False
        #: wanted only for the relay's own errand (SetTime): no readiness driving
        self.errand = False

    # -- queries -----------------------------------------------------------------------

    @property
    def controlled(self) -> bool:
        """True when the component confirmed our control."""
        return self.state is ControlState.CONTROLLED

    @property
    def ready(self) -> bool:
        """True when commands may be sent: controlled and READY (or waited long enough)."""
        if not self.controlled:
            return False
        if not self.managed:
            return True
        if self.hold_standby or self.status in NOT_OPERATIONAL:
            return False
        return self.status == READY or (
            self.ready_attempts >= self.profile.max_ready_attempts and self.ready_deadline is None
        )

    def next_deadline(self) -> float | None:
        """Earliest time :meth:`poll` has something to do."""
        times = [t for t in (self.deadline, self.ready_deadline) if t is not None]
        return min(times) if times else None

    # -- inputs ------------------------------------------------------------------------

    def want(self, wanted: bool, now: float) -> list[Outgoing]:
        """Start or stop wanting control."""
        if wanted == self.wanted:
            return []
        self.wanted = wanted
        self.hold_standby = False
        if wanted:
            if self.state in (ControlState.IDLE, ControlState.RELEASING):
                return self._request(now)
            return []
        if self.state in (ControlState.CONTROLLED, ControlState.REQUESTING):
            self.state = ControlState.RELEASING
            self.deadline = now + self.profile.response_timeout
            self.ready_deadline = None
            return [Outgoing("ReleaseControl", {})]
        self._idle()
        return []

    def on_confirm(self, code: int, now: float) -> list[Outgoing]:
        """ConfirmControl(response_code) arrived."""
        self.last_response = code
        if self.state not in (ControlState.REQUESTING, ControlState.CONTROLLED):
            return []
        if code == 1 and self.state is ControlState.CONTROLLED and self.status == EMERGENCY:
            # Management: a component in EMERGENCY answers even its controller's renewal
            # with NOT_AVAILABLE but keeps it as controller (and never times it out)
            renewal = self._renewal_period()
            self.deadline = now + renewal if renewal else None
            return []
        if code != 0:
            self.state = ControlState.REFUSED
            self.deadline = now + self.profile.retry_period
            self.ready_deadline = None
            return []
        first = self.state is ControlState.REQUESTING
        self.state = ControlState.CONTROLLED
        self.request_attempts = 0
        self.deadline = now + self._renewal_period()
        out: list[Outgoing] = []
        if not self.timeout_asked:
            self.timeout_asked = True
            out.append(Outgoing("QueryTimeout", {}))
        if first and self.status == READY:
            # READY seen before we held control was another controller's: Management is
            # READY only under a controller, so our control starts in STANDBY
            self.status = None
        if first and self.managed and not self.errand and not self.hold_standby:
            self.ready_attempts = 0
            out.extend(self._drive_ready(now))
        return out

    def on_reject(self, code: int, now: float) -> list[Outgoing]:
        """RejectControl(response_code): control ended (released, timed out, preempted)."""
        if self.state is ControlState.RELEASING or not self.wanted:
            self._idle()
            return []
        if self.state in (ControlState.CONTROLLED, ControlState.REQUESTING):
            self.state = ControlState.REFUSED
            self.ready_deadline = None
            self.deadline = now + min(self.profile.retry_period, self.profile.response_timeout)
        return []

    def on_timeout_report(self, seconds: int, now: float) -> None:
        """ReportTimeout(timeout): the component's control timeout, 0 = none."""
        self.timeout = float(seconds)
        if self.controlled:
            renewal = self._renewal_period()
            self.deadline = now + renewal if renewal else None

    def on_status(self, status: int, now: float) -> list[Outgoing]:
        """ReportStatus(status) arrived."""
        previous, self.status = self.status, status
        if (previous == EMERGENCY and status not in NOT_OPERATIONAL and status != READY
                and self.controlled and self.managed):
            # out of an emergency (cleared): back to READY before commanding again (unless
            # the operator's Standby holds or this is only the relay's errand)
            self.ready_attempts = 0
            return self._drive_ready(now)
        if self.errand or self.hold_standby:
            self.ready_deadline = None
        elif self.controlled and self.managed and status != READY:
            if status in NOT_OPERATIONAL:
                self.ready_deadline = None
            elif self.ready_attempts < self.profile.max_ready_attempts and (
                self.ready_deadline is None
            ):
                self.ready_deadline = now + self.profile.response_timeout
        elif status == READY:
            self.ready_deadline = None
            self.note = ""
        return []

    def on_command(self, name: str, now: float) -> None:
        """The relay sent Management command ``name`` on an operator's behalf (rule 2a)."""
        if name == "Standby":
            self.hold_standby = True
            self.ready_deadline = None
        elif name == "Resume":
            self.hold_standby = False
            self.ready_attempts = 0
            self.note = ""

    def set_authority(self, authority: int, now: float) -> list[Outgoing]:
        """Hold control with ``authority`` from now on (rule 2b)."""
        if authority == self.authority:
            return []
        lower = authority < self.authority
        self.authority = authority
        if not self.controlled:
            return []  # the next RequestControl carries it
        if lower:
            return [Outgoing("SetAuthority", {"authority_code": authority}),
                    Outgoing("QueryAuthority", {})]
        return [self._request_message(), Outgoing("QueryAuthority", {})]

    def on_lost(self) -> None:
        """The vehicle went silent: whatever we held is gone; ask again when it returns."""
        self._idle()
        self.status = None
        self.timeout_asked = False

    def on_found(self, now: float) -> list[Outgoing]:
        """The vehicle is back: re-request control if it is still wanted."""
        if self.wanted and self.state is ControlState.IDLE:
            return self._request(now)
        return []

    def poll(self, now: float) -> list[Outgoing]:
        """Do whatever is due at ``now``."""
        out: list[Outgoing] = []
        if self.deadline is not None and now >= self.deadline:
            self.deadline = None
            if self.state is ControlState.REQUESTING or self.state is ControlState.REFUSED:
                out.extend(self._request(now))
            elif self.state is ControlState.CONTROLLED:
                out.append(self._request_message())
                renewal = self._renewal_period()
                self.deadline = now + renewal if renewal else None
            elif self.state is ControlState.RELEASING:
                self.unanswered = True
                self._idle()
        if self.ready_deadline is not None and now >= self.ready_deadline:
            self.ready_deadline = None
            out.extend(self._drive_ready(now))
        return out

    # -- internals ---------------------------------------------------------------------

    def _request_message(self) -> Outgoing:
        return Outgoing("RequestControl", {"authority_code": self.authority})

    def _request(self, now: float) -> list[Outgoing]:
        self.state = ControlState.REQUESTING
        self.request_attempts += 1
        self.deadline = now + self.profile.response_timeout
        return [self._request_message()]

    def _renewal_period(self) -> float:
        if self.timeout is None:
            return self.profile.renewal_period
        if self.timeout == 0:
            return 0.0
        return max(self.timeout / 2.0, 0.1)

    def _drive_ready(self, now: float) -> list[Outgoing]:
        """One attempt to bring the component to READY."""
        if (not self.controlled or self.status == READY or self.status in NOT_OPERATIONAL
                or self.errand or self.hold_standby):
            return []
        if self.ready_attempts >= self.profile.max_ready_attempts:
            status = "unknown" if self.status is None else str(self.status)
            self.note = (f"did not reach READY after {self.ready_attempts} Resume attempts "
                         f"(status {status}); commanding anyway")
            return []
        self.ready_attempts += 1
        self.ready_deadline = now + self.profile.response_timeout
        return [Outgoing("Resume", {}), Outgoing("QueryStatus", {})]

    def _idle(self) -> None:
        self.state = ControlState.IDLE
        self.deadline = None
        self.ready_deadline = None
