"""Benchmark of the digital twin: simulated lab time ÷ wall time for the stepped-sine campaign.

The shipped stepped-sine frequency-response procedure (28 snapped points × 5 groups, 2^17
samples at 2 kHz each) on the realistic three-sensor rig (every datasheet term on, three
channels), through the same World call sequence the simulated plugins use. Prints the ratio
and the peak traced memory. Target ≥ 1000× on one core.

    python bench/twin.py [--steps N] [--channels 1|3]

"One core": BLAS threads are limited to one (set before NumPy loads), so the twin computes on
one core at a time; ``--pin`` also pins the process to a single CPU. The ratio is reported
against wall time (the target) and against the process's CPU time, which stays meaningful when
other jobs share the machine.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402 - after the thread limits on purpose
import resource  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from aatest.engine.steps import PlannedStep  # noqa: E402
from aatest.plugins.sensors.sr207 import SR207, SR207Unit  # noqa: E402
from aatest.twin.api import World, realistic_rig_model, run_step  # noqa: E402
from aatest.twin.model import RigModel  # noqa: E402

FS_HZ = 2000.0
#: glibc's largest dynamic mmap threshold on 64-bit systems
_MMAP_THRESHOLD_MAX_BYTES = 32 * 2**20
SAMPLES = 2**17
#: cycle counts of the 28 published points (docs/method.md §4.4), f = c·Fs/N
CYCLES = (26, 31, 38, 45, 54, 65, 66, 78, 94, 112, 131, 135, 163, 195, 197, 234, 262, 280, 328,
          337, 393, 404, 459, 485, 524, 582, 590, 655)
GROUPS = (("position-0.2", None), ("accel-1", 1.0), ("accel-10", 10.0), ("accel-100", 100.0),
          ("accel-400", 400.0))


def _own_steps(settle_s: float = 5.0) -> list[PlannedStep]:
    """The 140 steps built directly (used when the planner is unavailable)."""
    steps = []
    for group, accel in GROUPS:
        for c in CYCLES:
            f = c * FS_HZ / SAMPLES
            amp = 0.2 if accel is None else accel / (2 * np.pi * f) ** 2
            steps.append(PlannedStep(
                id=f"{group}-{c}", kind="sine", axis="inner", duration_s=SAMPLES / FS_HZ,
                settle_s=settle_s, samples=SAMPLES, frequency_hz=f, cycles=c, amplitude_deg=amp,
                accel_dps2=amp * (2 * np.pi * f) ** 2, group=group))
    return steps


def _shipped_steps() -> list[PlannedStep] | None:
    """The shipped procedure's plan, when the planner and procedure are importable."""
    try:
        import aatest
        from aatest.engine.procedure.loader import load_procedure
        from aatest.engine.procedure.planner import expand

        path = Path(aatest.__file__).parent / "procedures" / "stepped-sine-frequency-response.yaml"
        return [s for s in expand(load_procedure(path)).steps if s.recorded]
    except Exception as exc:  # noqa: BLE001 - the bench falls back to its own step list
        print(f"(shipped procedure unavailable: {exc}; using the bench's own 140 steps)")
        return None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=0, help="run only the first N steps")
    parser.add_argument("--channels", type=int, choices=(1, 3), default=3)
    parser.add_argument("--own", action="store_true", help="use the bench's own step list")
    parser.add_argument("--pin", action="store_true", help="pin the process to one CPU")
    args = parser.parse_args()
    steps = (None if args.own else _shipped_steps()) or _own_steps()
    if args.steps:
        steps = steps[: args.steps]
    model = realistic_rig_model((SR207Unit() if args.channels == 3 else SR207()).datasheet())
    if args.pin and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    _run(model, steps[:1])  # warm caches (filters, imports) outside the timing
    # glibc's malloc as in ``aatest run``'s process, which has freed a block of its largest
    # mmap threshold (32 MiB) before the steps: without that, the heap is trimmed after every
    # step and each step faults its working set in again (measured 12-30 ms of system time
    # per step, a third of the twin's CPU, that the run does not pay)
    np.ones(_MMAP_THRESHOLD_MAX_BYTES // 8 - 1024)  # (its header and page rounding inside)
    t_wall, t_cpu = time.perf_counter(), time.process_time()
    lab_s = _run(model, steps)
    wall_s, cpu_s = time.perf_counter() - t_wall, time.process_time() - t_cpu
    tracemalloc.start()
    _run(model, steps[:3])
    traced_peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    rss_peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"steps: {len(steps)}  samples/step: {steps[0].samples}  channels: {len(model.sensors)}")
    print(f"simulated lab time: {lab_s:.1f} s  wall time: {wall_s:.2f} s  CPU time: {cpu_s:.2f} s "
          f"({1e3 * wall_s / len(steps):.1f} ms/step wall, {1e3 * cpu_s / len(steps):.1f} ms CPU)")
    print(f"lab time / wall time: {lab_s / wall_s:.0f}x   "
          f"lab time / CPU time: {lab_s / cpu_s:.0f}x")
    print(f"peak memory: {rss_peak_mib:.0f} MiB RSS (process), "
          f"{traced_peak / 2**20:.0f} MiB traced in one step's synthesis")


def _run(model: RigModel, steps: list[PlannedStep]) -> float:
    """Run ``steps`` on a fresh World; return the simulated lab time (s)."""
    world = World(model, seed=2024)
    world.motor_on = True
    for step in steps:
        run_step(world, step)
    return world.lab_time_s


if __name__ == "__main__":
    main()
