"""What a station's run controller published, collected by a test (the controller's ``emit``)."""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Any


@dataclass
class Events:
    """What the controller published, and a latch set by the run's last event."""

    seen: list[dict[str, Any]] = field(default_factory=list)
    ended: threading.Event = field(default_factory=threading.Event)

    def __call__(self, event: dict[str, Any]) -> None:
        self.seen.append(event)
        if event["type"] == "finished" or (event["type"] == "stopped" and "exit_code" in event):
            self.ended.set()
