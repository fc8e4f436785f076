"""A rich progress bar for long runs: step i/n, what is moving, remaining lab time."""

from __future__ import annotations

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
        self._progress = Progress(
            TextColumn("[bold]{task.fields[label]}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("lab time left {task.fields[lab_left]}"),
            TimeElapsedColumn(),
            console=Console(stderr=True),
            disable=not enabled,
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
        self._progress.update(self._task, label=f"{step.id}: {describe(step)}")

    def end(self, step: PlannedStep) -> None:
        """Count the step as done and take its lab time off the time left."""
        self._remaining_lab_s -= step.lab_duration_s
        lab_left = self._fmt(max(self._remaining_lab_s, 0))
        self._progress.update(self._task, advance=1, lab_left=lab_left)
