"""Benchmark ``aatest run`` end to end: lab time ÷ wall time per phase, peak RSS, recording MB.

The shipped stepped-sine frequency-response procedure (136 steps of 2^17 samples at 2 kHz) runs
on the simulated rig through the same calls as ``aatest run`` (:mod:`aatest.engine.run.session`),
each phase timed on its own:

- ``record``  the runner drives the twin and writes one step file per step;
- ``merge``   the step files become ``recording.mcap`` (and are deleted);
- ``analyse`` the recording is read and the procedure's analyses run;
- ``report``  uncertainty, verdicts, results.json, the HTML certificate (and its signature).

Before ``record``, untimed like the procedure's loading, the plan's checks run as ``aatest
run`` makes them before anything moves (:func:`aatest.engine.plan_checks.refuse_unrunnable`:
the report's template is compiled there, and the render takes it).

The analyses' figures are drawn aside, as ``aatest run`` draws them
(:func:`aatest.presentation.figures.drawing_aside`): their processes start in ``merge``,
once the step files are merged, and import matplotlib meanwhile; ``analyse`` only asks for
the figures, and ``report`` takes them after the verdicts, waiting for those not drawn yet.

During ``record`` a child process makes the sync pass's per-step work as each step file is
written (:mod:`aatest.early.analysis`, as ``aatest run`` does; off with
``AATEST_EARLY_ANALYSIS=0``); it is ended and reaped at the end of ``merge``, so its CPU
seconds count there, and the bench prints how many steps ``analyse`` took from it.

It prints wall and CPU seconds per phase (CPU counts the analysis pass's forked workers,
:func:`aatest.plugins.analysis.sync.relations`), lab ÷ wall (issue 26 asks ≥ 1000× on this 2-core
machine) and lab ÷ CPU (meaningful when other jobs share the machine), the peak resident memory
of each phase and of the whole process (issue 14: ≤ 800 MB, not growing with the number of
steps — compare ``--steps 68`` with the full run), the workers' peak (each; this process plus
all workers is an upper bound, as a forked worker's RSS counts pages it shares) and the
recording's size in MB; and the peak memory of the whole process tree as the kernel's
proportional set size (PSS, sampled by :mod:`tree_memory` from a separate process: shared
pages counted once), the figure to hold against 800 MB. ``AATEST_WORKERS=1`` runs the
analysis pass in this process alone. Last, the whole run's wall and CPU time (all its processes,
the figures' ones included, which are reaped after the report phase), how busy the CPUs were
(CPU ÷ (wall × CPUs)), and the lab ÷ wall that the same CPU time would give with every CPU
busy throughout: the most any better overlap of the same work can reach, so a target above
it needs less CPU.

    python bench/end_to_end.py [--steps N] [--dir DIR] [--seed 0] [--analyse-only RUN_DIR]
    python bench/end_to_end.py --procedure src/aatest/procedures/static-multi-position.yaml

Operator prompts (pivot, re-mount) are confirmed unattended, as ``aatest run
--confirm-prompts auto`` does, so the procedures with prompts (static multi-position,
pivoted misalignment) can be timed too.

    python bench/end_to_end.py --compare BASE/src [--rounds 3] [--steps N]

``--compare`` runs the benchmark in fresh processes alternately on another checkout's
``src`` (put first on ``PYTHONPATH``: a baseline commit, e.g. from ``git worktree add``) and on
this one, ``--rounds`` times each, and prints each phase's median wall and CPU seconds for
both and their ratios: on a machine shared with other work, only ratios measured side by side
mean anything.

``--analyse-only`` re-times the analyse and report phases on an existing run directory. Peak
RSS per phase uses Linux's resettable high-water mark (``/proc/self/clear_refs``, which resets
``getrusage``'s ``ru_maxrss`` too); the whole-run figure is the largest phase peak.
"""

from __future__ import annotations

import argparse
import contextlib
import inspect
import json
import os
import resource
import shutil
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

from child_run import child_json
from tree_memory import TreeMemory  # bench/ is the script's directory, hence on sys.path

from aatest.engine import registry
from aatest.engine.run import session
from aatest.engine.run.events import AutoResponder, RunEvents
from aatest.engine.run.rig import build_rig
from aatest.engine.run.run_state import open_state
from aatest.engine.run.runner import procedure_sha256, run_metadata, run_plan
from aatest.recording import RECORDING_NAME, RunRecorder

try:
    from aatest.parallel.forked import cpu_workers
except ImportError:  # a checkout from before aatest.parallel (--compare)
    from aatest.engine.forked import cpu_workers  # type: ignore[no-redef,import-not-found]

PROCEDURE = Path(__file__).resolve().parents[1] / "src/aatest/procedures" \
    / "stepped-sine-frequency-response.yaml"
MB = 1e6
T = TypeVar("T")


def _reset_peak() -> bool:
    """Reset the kernel's resident high-water mark of this process (Linux ≥ 4.0)."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
    except OSError:
        return False
    return True


def _peak_mb() -> float:
    """VmHWM of this process in MB (since the last reset), else ru_maxrss."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024 / MB
    except OSError:
        pass
    return _maxrss_mb()


def _maxrss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / MB


def _children_peak_mb() -> float:
    """The largest peak RSS of any finished child process (the analysis pass's workers)."""
    return resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024 / MB


def _cpu_s() -> float:
    """CPU seconds of this process and of its finished children (the forked workers)."""
    own, children = (resource.getrusage(who)
                     for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


class Phases:
    """Wall, CPU and peak RSS of each named phase."""

    def __init__(self) -> None:
        self.rows: list[tuple[str, float, float, float]] = []
        #: wall and CPU seconds when the first phase started
        self.started: tuple[float, float] | None = None
        #: wall and CPU seconds of the whole run, every process reaped (:meth:`close`)
        self.whole: tuple[float, float] | None = None

    def close(self) -> None:
        """Take the whole run's wall and CPU seconds since the first phase began (call it
        once every process of the run is reaped: the figures' ones end with the drawing
        block, after the report phase)."""
        assert self.started is not None
        self.whole = (time.perf_counter() - self.started[0], _cpu_s() - self.started[1])

    def time(self, name: str, action: Callable[[], T]) -> T:
        _reset_peak()
        wall, cpu = time.perf_counter(), _cpu_s()
        if self.started is None:
            self.started = (wall, cpu)
        result = action()
        self.rows.append((name, time.perf_counter() - wall, _cpu_s() - cpu, _peak_mb()))
        return result


def _preflight(prepared: Any, out: Path) -> None:
    """The plan's checks before anything moves, as ``aatest run`` makes them (not timed, as
    the procedure's loading is not): its report template is compiled there."""
    from aatest.engine.plan_checks import refuse_unrunnable

    refuse_unrunnable(prepared, out)


def _record(prepared: Any, out: Path, seed: int, phases: Phases) -> Any:
    """Record the run; what the analysis made during the record phase (None without)."""
    plan = prepared.plan
    state = open_state(out, plan.procedure, procedure_sha256(prepared.text), seed, False)
    recorder = RunRecorder(out)
    rig = build_rig(prepared.rig_config, plan.sensor, seed)
    meta = run_metadata(plan, rig, prepared.text, seed, "bench")
    meta["report_template"] = plan.report_template
    recorder.write_run_metadata(meta)
    # unattended, as `aatest run --confirm-prompts auto`: a procedure with operator prompts
    # (pivot, re-mount) runs too, each prompt logged to stderr
    events = RunEvents(responder=AutoResponder())
    with _early_analysis(prepared, recorder) as early:
        phases.time("record", lambda: run_plan(plan, rig, early.recorder, state, out,
                                               show_progress=False, events=events))

        def merge() -> Any:
            # the analysis made during the record phase is collected (its child reaped) here;
            # then, as `aatest run` does, the run is marked finished and its step files go
            results = _finish_recording(recorder, early)
            state.finished = True
            state.save(out)
            recorder.prune_step_files()
            return results

        return phases.time("merge", merge)


class _NoEarly:
    """A checkout from before :mod:`aatest.early.analysis`: nothing made early."""

    def __init__(self, recorder: Any) -> None:
        self.recorder = recorder

    def results(self) -> None:
        return None


def _early_analysis(prepared: Any, recorder: Any) -> contextlib.AbstractContextManager[Any]:
    """The per-step analysis during the record phase, as ``aatest run`` makes it (none in a
    checkout without it, or with ``AATEST_EARLY_ANALYSIS=0``)."""
    try:
        from aatest.early.analysis import early_analysis
    except ImportError:  # a checkout from before aatest.early (--compare)
        try:
            from aatest.engine.run.early_analysis import early_analysis  # type: ignore[no-redef,import-not-found]
        except ImportError:
            return contextlib.nullcontext(_NoEarly(recorder))
    return early_analysis(prepared.plan, recorder, prepared.envelope)


def _analyse_and_report(prepared: Any, out: Path, phases: Phases, recorded_here: bool,
                        early: Any = None) -> tuple[float, int, int]:
    """Time the analyse and report phases; the lab time (s) the results state and the number of
    steps analysed and of steps the analysis took from the record phase. The lab time is the
    plan's when
    this bench recorded the run, else the recorded steps' own (``--analyse-only``: the run may
    be of another procedure or length than the options given), as ``aatest analyze`` does."""
    from aatest.engine.analysis.passes import run_analyses
    from aatest.engine.analysis.results_file import build_results
    from aatest.recording import read_dataset

    def analyse() -> tuple[Any, Any]:
        data = read_dataset(out)
        if early is not None:
            early.offer(data)
        return data, run_analyses(data, list(data.metadata.get("analysis", [])))

    template = prepared.plan.report_template or "calibration-certificate"

    def report() -> None:
        with _report_prepared(template, out):
            decided = getattr(session, "decided_results", None)
            if decided is not None:  # the figures taken last: drawn aside meanwhile
                results = decided(data, analysis, lab_s, 0.0)
            else:  # a checkout from before the figures were drawn aside (--compare)
                results = session.decide(build_results(data, analysis, lab_s, 0.0), data)
            session.render_and_sign(results, out, template, None, None)

    data, analysis = phases.time("analyse", analyse)
    lab_s = (prepared.plan.lab_duration_s if recorded_here
             else sum(s.step.lab_duration_s for s in data.steps))
    phases.time("report", report)
    return float(lab_s), len(data.steps), early.offered if early is not None else 0


def _drawing_aside() -> contextlib.AbstractContextManager[Any]:
    """The figures drawn aside over the run, as ``aatest run`` draws them
    (:func:`aatest.presentation.figures.drawing_aside`; none in a checkout from before): their
    processes start at the end of the record phase (``session.finish_recording``), or at the
    first figure (``--analyse-only``, a checkout from before)."""
    try:
        from aatest.presentation.figures import drawing_aside
    except ImportError:
        return contextlib.nullcontext()
    return drawing_aside()


def _finish_recording(recorder: Any, early: Any) -> Any:
    """Merge and collect what the early analysis made, as `aatest run` does (a checkout from
    before session.finish_recording merges and collects only)."""
    finish = getattr(session, "finish_recording", None)
    if finish is None:
        recorder.finalize()
        return early.results()
    return finish(recorder, early)


def _report_prepared(template: str, out: Path) -> contextlib.AbstractContextManager[Any]:
    """The report plugin prepares its render (and what of the run directory it prepares) over
    the whole phase, as `aatest run` does; a checkout from before session.report_prepared has
    none, one from before its ``run_dir`` prepares the render only."""
    prepared = getattr(session, "report_prepared", None)
    if prepared is None:
        return contextlib.nullcontext()
    if "run_dir" in inspect.signature(prepared).parameters:
        return prepared(template, out)
    return prepared(template)


def _pinned() -> contextlib.AbstractContextManager[Any]:
    """The run's single reading of the installed plugins, as ``aatest run`` does (a checkout
    from before :func:`aatest.engine.registry.pinned` reads them on every lookup)."""
    pinned = getattr(registry, "pinned", None)
    return pinned() if pinned is not None else contextlib.nullcontext()


def _child_rows(src: Path, argv: list[str]
                ) -> tuple[list[tuple[str, float, float]], float, int]:
    """Run this benchmark in a fresh process on the checkout ``src``; its phases, lab s and
    the steps the analysis took from the record phase."""
    doc = child_json(__file__, src, ["--json", *argv], "benchmark")
    return [tuple(r) for r in doc["phases"]], float(doc["lab_s"]), int(doc.get("taken", 0))


def compare(base_src: Path, rounds: int, argv: list[str]) -> None:
    """Alternate the baseline checkout and this one, ``rounds`` times; print median ratios."""
    this_src = Path(__file__).resolve().parents[1] / "src"
    runs: dict[str, list[list[tuple[str, float, float]]]] = {"base": [], "this": []}
    lab_s = 0.0
    for i in range(rounds):
        for label, src in (("base", base_src), ("this", this_src)):
            rows, lab_s, taken = _child_rows(src, argv)
            runs[label].append(rows)
            total = sum(r[1] for r in rows)
            print(f"round {i + 1} {label}: total {total:.2f} s wall, lab ÷ wall "
                  f"{lab_s / total:.0f}x, {taken} steps analysed during the record phase; "
                  f"load average {os.getloadavg()[0]:.1f}", flush=True)
    names = [r[0] for r in runs["this"][0]] + ["total"]

    def median(label: str, name: str, col: int) -> float:
        return statistics.median(sum(float(r[col]) for r in rows if name in (r[0], "total"))
                                 for rows in runs[label])

    print(f"median of {rounds} rounds: base {base_src} vs this {this_src}")
    print(f"  {'phase':<8} {'base wall':>10} {'this wall':>10} {'ratio':>6} "
          f"{'base CPU':>9} {'this CPU':>9} {'ratio':>6}")
    for name in names:
        bw, tw, bc, tc = median("base", name, 1), median("this", name, 1), \
            median("base", name, 2), median("this", name, 2)
        print(f"  {name:<8} {bw:10.2f} {tw:10.2f} {bw / tw:6.2f} {bc:9.2f} {tc:9.2f} "
              f"{bc / tc:6.2f}")
    base_total, this_total = median("base", "total", 1), median("this", "total", 1)
    print(f"lab ÷ wall: base {lab_s / base_total:.0f}x, this {lab_s / this_total:.0f}x "
          f"(×{base_total / this_total:.2f} side by side; target ≥ 1000x on an idle machine); "
          "load average " + ", ".join(f"{x:.1f}" for x in os.getloadavg()) +
          f" on {os.cpu_count()} CPUs")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--procedure", type=Path, default=PROCEDURE)
    parser.add_argument("--steps", type=int, default=None, help="only the first N steps")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--dir", type=Path, default=None, help="run directory (kept)")
    parser.add_argument("--analyse-only", type=Path, default=None, metavar="RUN_DIR")
    parser.add_argument("--compare", type=Path, default=None, metavar="BASE_SRC",
                        help="alternate with the checkout whose src directory this is")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.compare is not None:
        argv = [f"--steps={args.steps}"] if args.steps is not None else []
        compare(args.compare.resolve(), args.rounds, [*argv, f"--seed={args.seed}"])
        return
    prepared = session.prepare(args.procedure, None)
    if args.steps is not None:
        prepared.plan = prepared.plan.model_copy(
            update={"steps": prepared.plan.steps[:args.steps]})
    phases = Phases()
    with TreeMemory() as tree:
        with _pinned(), _drawing_aside():
            early = None
            if args.analyse_only is not None:
                out = args.analyse_only
            else:
                out = args.dir or Path(tempfile.mkdtemp(prefix="aatest-bench-e2e-")) / "run"
                if out.exists():
                    shutil.rmtree(out)
                _preflight(prepared, out)
                early = _record(prepared, out, args.seed, phases)
            lab_s, steps, taken = _analyse_and_report(prepared, out, phases,
                                                      args.analyse_only is None, early)
        # the drawing block has ended, its processes reaped; the memory sampler (a child too)
        # still runs, so its CPU is not counted
        phases.close()
    recording_mb = (out / RECORDING_NAME).stat().st_size / MB
    if args.json:
        print(json.dumps({"phases": [r[:3] for r in phases.rows], "lab_s": lab_s,
                          "taken": taken}))
        if args.dir is None and args.analyse_only is None:
            shutil.rmtree(out.parent, ignore_errors=True)
        return
    _print_summary(prepared.plan.procedure, out, phases, lab_s, steps, taken, recording_mb,
                   tree.peak_mb)


def _print_summary(procedure: str, out: Path, phases: Phases, lab_s: float, steps: int,
                   taken: int, recording_mb: float, tree_peak_mb: float | None) -> None:
    """The phases' table and the run's ratios, memory and load, as printed."""
    print(f"{procedure}: {steps} steps, lab time {lab_s:.0f} s,"
          f" recording {recording_mb:.1f} MB ({out})")
    print(f"analysis: {taken} of {steps} steps' sync-pass work taken from the record phase "
          "(AATEST_EARLY_ANALYSIS=0: none)")
    print(f"  {'phase':<8} {'wall/s':>8} {'CPU/s':>8} {'peak RSS/MB':>12}")
    for name, wall, cpu, peak in phases.rows:
        print(f"  {name:<8} {wall:8.2f} {cpu:8.2f} {peak:12.0f}")
    wall = sum(r[1] for r in phases.rows)
    cpu = sum(r[2] for r in phases.rows)
    peak = max([r[3] for r in phases.rows] + [_maxrss_mb()])  # the reset lowers ru_maxrss too
    print(f"  {'total':<8} {wall:8.2f} {cpu:8.2f} {peak:12.0f}")
    workers = cpu_workers()
    child_mb = _children_peak_mb()
    # a worker's RSS counts the pages it shares with this process (forked): the sum is an
    # upper bound of the run's resident memory, not an estimate
    bound = peak + workers * child_mb
    print(f"analysis workers: {workers} forked, each ≤ {child_mb:.0f} MB resident; "
          f"this process and its workers ≤ {bound:.0f} MB together (an upper bound: each "
          "worker's RSS counts again the pages it shares with this process)")
    tree_mb = "n/a" if tree_peak_mb is None else f"{tree_peak_mb:.0f} MB"
    print(f"lab ÷ wall {lab_s / wall:.0f}x (target ≥ 1000x, issue 26), "
          f"lab ÷ CPU {lab_s / cpu:.0f}x; "
          f"peak memory of the process tree (PSS) {tree_mb} (target ≤ 800 MB; RSS of this "
          f"process {peak:.0f} MB); recording {recording_mb:.1f} MB")
    # how far packing the same work better could go: with every CPU busy throughout, the
    # run would take CPU ÷ CPUs of wall (every process of the run: the early child, the
    # workers, the render child and the figures' processes, reaped after the report phase)
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    cpus = cpus or 1
    assert phases.whole is not None
    whole_wall, whole_cpu = phases.whole
    print(f"whole run {whole_wall:.2f} s wall, {whole_cpu:.2f} s CPU of all its processes: the "
          f"CPUs were busy {100.0 * whole_cpu / (whole_wall * cpus):.0f} % of it (CPU ÷ (wall × "
          f"{cpus} CPUs)); with all {cpus} busy throughout, this CPU time allows at most "
          f"{lab_s * cpus / whole_cpu:.0f}x lab ÷ wall")
    # the machine is shared: wall time says as much about the other jobs as about this one
    print("load average " + ", ".join(f"{x:.1f}" for x in os.getloadavg()) +
          f" on {os.cpu_count()} CPUs")


if __name__ == "__main__":
    main()
