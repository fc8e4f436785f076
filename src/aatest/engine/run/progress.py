"""Progress of a run: a rich bar on a terminal, one plain line per step in a log.

On a terminal the bar shows step i/n, what is moving and the lab time left. Without one (a CI
log, ``aatest run … | tee``) a redrawn bar is noise and a fixed-width line gets cut, so each
step ends with one full line: ``[3/136] s003 static inner 0°, outer 0° … done in 0.1 s``.
"""

from __future__ import annotations

import sys
import time
from types import TracebackType

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from aatest.engine.steps import Plan, PlannedStep


def describe(step: PlannedStep) -> str:
    """A short human label of what the table is doing in a step."""
    if step.kind == "sine":
        amplitude = f"{step.amplitude_deg:.4f}° ({step.accel_dps2:g} °/s²)"
        return f"sine {step.frequency_hz:.4f} Hz, {amplitude}"
    if step.kind == "constant_rate":
        outer = f", outer {step.outer_rate_dps:g} °/s" if step.outer_rate_dps else ""
        return f"rate {step.rate_dps:g} °/s{outer}"
    if step.kind == "chamber":
        return f"chamber → {step.temperature_c:g} °C"
    return f"static inner {step.inner_deg:g}°, outer {step.outer_deg:g}°"


class StepProgress:
    """Context manager wrapping rich.Progress with lab-time bookkeeping."""

    def __init__(self, plan: Plan, done: set[str], enabled: bool = True) -> None:
        self._plan = plan
        self._remaining_lab_s = sum(s.lab_duration_s for s in plan.steps if s.id not in done)
        console = Console(stderr=True)
        #: without a terminal: one plain line per finished step instead of the bar
        self._lines = enabled and not console.is_terminal
        self._count = len(done & {s.id for s in plan.steps})
        self._started = time.monotonic()
        self._progress = Progress(
            TextColumn("[bold]{task.fields[label]}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("lab time left {task.fields[lab_left]}"),
            TimeElapsedColumn(),
            console=console,
            disable=not enabled or self._lines,
        )
        self._task = self._progress.add_task(
            "run", total=len(plan.steps), completed=len(done & {s.id for s in plan.steps}),
            label="starting", lab_left=self._fmt(self._remaining_lab_s),
        )

    @staticmethod
    def _fmt(seconds: float) -> str:
        h, rem = divmod(int(seconds), 3600)
        return f"{h}:{rem // 60:02d}:{rem % 60:02d}"

    def __enter__(self) -> StepProgress:
        self._progress.start()
        return self

    def __exit__(
        self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None
    ) -> None:
        self._progress.stop()

    def begin(self, step: PlannedStep) -> None:
        """Show the step that starts now."""
        self._started = time.monotonic()
        self._progress.update(self._task, label=f"{step.id}: {describe(step)}")

    def end(self, step: PlannedStep) -> None:
        """Count the step as done and take its lab time off the time left."""
        self._remaining_lab_s -= step.lab_duration_s
        lab_left = self._fmt(max(self._remaining_lab_s, 0))
        self._progress.update(self._task, advance=1, lab_left=lab_left)
        self._count += 1
        if self._lines:
            took_s = time.monotonic() - self._started
            print(f"[{self._count}/{len(self._plan.steps)}] {step.id} {describe(step)} … done "
                  f"in {took_s:.1f} s (lab time left {lab_left})", file=sys.stderr, flush=True)
