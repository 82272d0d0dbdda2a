"""The Mission Spooler of a simulated vehicle (AS6009). No I/O.

As the JSIDL protocol has it, only the controlling client spools or changes a mission:
SpoolMission in INIT (nothing held) stores one mission; RunMission starts it (or a task or
message of it) when it is held or PAUSED; PauseMission while RUNNING, ResumeMission while
PAUSED; Insert/Remove messages and tasks while PAUSED; AbortMission at any time clears it.
Anything else is ignored, as a real spooler does. A running mission executes its
messages in order, depth first through the task tree, one every :data:`MESSAGE_SECONDS`
(a blocking message holds the next one back twice as long); the sim records each as
executed when it starts rather than acting on it. When the last message is done the
mission is FINISHED and cleared.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

INIT, RUNNING, PAUSING, PAUSED, ABORTING, ABORTED, BLOCKED, FINISHED = range(8)
NON_ERROR, LOST_CONTROL = 0, 1
#: seconds one mission message takes to execute
MESSAGE_SECONDS = 1.0


@dataclass(slots=True)
class Mission:
    """One spooled mission: its tasks as SpoolMission carries them."""

    mission_id: int
    creator: dict[str, int]
    tasks: list[dict[str, Any]]


@dataclass
class Spooler:
    """The spooler's state (see the module docstring); ``executed`` lists ``(mission,
    task, uid)`` of each message run."""

    mission: Mission | None = None
    status: int = INIT
    detail: int = NON_ERROR
    last_id: int = 0
    queue: list[tuple[int, dict[str, Any]]] = field(default_factory=list)
    next_at: float = 0.0
    executed: list[tuple[int, int, int]] = field(default_factory=list)

    # -- orders -------------------------------------------------------------------------

    def spool(self, fields: dict[str, Any]) -> bool:
        if self.mission is not None:
            return False
        info = fields["mission_info"]
        self.mission = Mission(info["mission_id"], dict(info["source_id"]),
                               [dict(t) for t in fields["mission_plan"]])
        self.status, self.detail, self.last_id = INIT, NON_ERROR, info["mission_id"]
        self.queue = []
        return True

    def run(self, fields: dict[str, Any], now: float) -> bool:
        if not self._held(fields.get("mission_id")) or self.status not in (INIT, PAUSED):
            return False
        assert self.mission is not None
        order = self._order()
        task, uid = fields.get("task_id"), fields.get("message_uid")
        if task is not None or uid is not None:
            start = next((i for i, (t, m) in enumerate(order)
                          if (task is None or t == task) and (uid is None or m["uid"] == uid)),
                         None)
            if start is None:
                return False
            order = order[start:]
        elif self.status == PAUSED:
            order = self.queue
        self.queue, self.status, self.detail = order, RUNNING, NON_ERROR
        self.next_at = now
        return True

    def pause(self, fields: dict[str, Any]) -> bool:
        if not self._held(fields.get("mission_id")) or self.status != RUNNING:
            return False
        self.status = PAUSED
        return True

    def resume(self, fields: dict[str, Any], now: float) -> bool:
        if not self._held(fields.get("mission_id")) or self.status != PAUSED:
            return False
        self.status, self.next_at = RUNNING, now
        return True

    def abort(self, fields: dict[str, Any]) -> bool:
        if not self._held(fields.get("mission_id")):
            return False
        self.mission, self.queue, self.status = None, [], ABORTED
        return True

    def lost_control(self) -> None:
        """The controlling client is gone: a running mission pauses (JSIDL)."""
        if self.status == RUNNING:
            self.status, self.detail = PAUSED, LOST_CONTROL

    def insert_messages(self, fields: dict[str, Any]) -> bool:
        info = fields["mission_and_task_info"]
        task = self._task(info["mission_id"], info["task_id"])
        if task is None:
            return False
        messages = task["task_data"]["jaus_messages"]
        at = next((i for i, m in enumerate(messages) if m["uid"] == info["uid"]), None)
        if at is None:
            return False
        at += 1 if info["insert_location"] == 1 else 0
        messages[at:at] = [dict(m) for m in fields["insert_message_list"]]
        self._requeue()
        return True

    def remove_messages(self, fields: dict[str, Any]) -> bool:
        info = fields["mission_info"]
        task = self._task(info["mission_id"], info["task_id"])
        if task is None:
            return False
        gone = {m["uid"] for m in fields["message_list"]}
        data = task["task_data"]
        data["jaus_messages"] = [m for m in data["jaus_messages"] if m["uid"] not in gone]
        self._requeue()
        return True

    def insert_task(self, fields: dict[str, Any]) -> bool:
        info = fields["mission_and_task_info"]
        if self._task(info["mission_id"], info["task_id"]) is None or self.mission is None:
            return False
        tasks = self.mission.tasks
        new = fields["task"]
        at = next(i for i, t in enumerate(tasks) if t["task_data"]["task_info"]["task_id"]
                  == info["task_id"]) + (1 if info["insert_location"] == 1 else 0)
        tasks[at:at] = [{"task_data": {"task_info": new["task_data"]["task_info"],
                                       "jaus_messages": list(new["task_data"]["task_messages"])},
                         "sub_tasks": list(new["sub_tasks"])}]
        self._requeue()
        return True

    def remove_tasks(self, fields: dict[str, Any]) -> bool:
        info = fields["mission_and_task_info"]
        if self._task(info["mission_id"], info["task_id"]) is None or self.mission is None:
            return False
        gone = {t["task_id"] for t in fields["remove_task_list"]}
        self.mission.tasks = [t for t in self.mission.tasks
                              if t["task_data"]["task_info"]["task_id"] not in gone]
        self._requeue()
        return True

    # -- time -----------------------------------------------------------------------------

    def step(self, now: float) -> None:
        """Execute the messages that are due."""
        while self.status == RUNNING and self.mission is not None and now >= self.next_at:
            if not self.queue:
                self.mission, self.status, self.detail = None, FINISHED, NON_ERROR
                return
            task_id, message = self.queue.pop(0)
            self.executed.append((self.mission.mission_id, task_id, message["uid"]))
            blocking = message.get("blocking") == 1
            self.next_at = max(self.next_at, now - MESSAGE_SECONDS) + (
                2 * MESSAGE_SECONDS if blocking else MESSAGE_SECONDS)

    # -- reports --------------------------------------------------------------------------

    def report_status(self) -> dict[str, Any]:
        return {"type": 0, "id": self.last_id, "status": self.status,
                "secondary_status": self.detail}

    def report_stored(self) -> dict[str, Any]:
        held = [self.mission] if self.mission is not None else []
        return {"mission_list": [{"mission_id": m.mission_id, "creator_id": m.creator}
                                 for m in held]}

    def report_plan(self, fields: dict[str, Any]) -> dict[str, Any] | None:
        mission = self.mission
        if mission is None or mission.mission_id != fields.get("mission_id") \
                or not mission.tasks:
            return None
        return {"mission_info": {"mission_id": mission.mission_id, "source_id": mission.creator},
                "task": mission.tasks[0]}

    # -- helpers --------------------------------------------------------------------------

    def _held(self, mission_id: Any) -> bool:
        return self.mission is not None and (mission_id is None
                                             or mission_id == self.mission.mission_id)

    def _task(self, mission_id: int, task_id: int) -> dict[str, Any] | None:
        if not self._held(mission_id) or self.status != PAUSED:
            return None
        assert self.mission is not None
        return next((t for t in self.mission.tasks
                     if t["task_data"]["task_info"]["task_id"] == task_id), None)

    def _order(self) -> list[tuple[int, dict[str, Any]]]:
        """Every message, depth first from the first task through its sub-task indices."""
        assert self.mission is not None
        tasks = self.mission.tasks
        out: list[tuple[int, dict[str, Any]]] = []
        seen: set[int] = set()

        def visit(index: int) -> None:
            if index in seen or not 0 <= index < len(tasks):
                return
            seen.add(index)
            task = tasks[index]
            task_id = task["task_data"]["task_info"]["task_id"]
            out.extend((task_id, m) for m in task["task_data"]["jaus_messages"])
            for child in task["sub_tasks"]:
                visit(child["child_task_index"])

        for index in range(len(tasks)):
            visit(index)
        return out

    def _requeue(self) -> None:
        """After a change while PAUSED: what is left to run, from the next message on."""
        done = {(t, uid) for m, t, uid in self.executed
                if self.mission is not None and m == self.mission.mission_id}
        self.queue = [(t, m) for t, m in self._order() if (t, m["uid"]) not in done]
