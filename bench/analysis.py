"""Benchmark: analyse the full stepped-sine campaign (docs/method.md §4.4) and print samples/s.

The campaign is the published 28-point frequency grid in the constant-amplitude (0.2°) and
constant-acceleration (1, 10, 100, 400 °/s²) groups, inside the sensor/table envelope, each
record 2^17 samples at 2 kHz, simulated on the twin (realistic rig). The analyses are the
procedure's ``[sync, frf, thd, snr, transfer_function]`` (thd/snr are computed by frf).
"Samples analysed" counts table-log samples of every step (the DAQ log is as long again).

    python bench/analysis.py [--samples 131072] [--seed 1]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from aatest.engine.analysis import plugins
from aatest.engine.interfaces import AnalysisContext, AnalysisOutput
from aatest.engine.steps import PlannedStep
from aatest.twin.api import realistic_rig_model, simulate_dataset

FS_HZ = 2000.0
#: published cycle counts in a 2^17-sample record (docs/method.md §4.4: 28 points)
CYCLES_2_17 = (26, 31, 38, 45, 54, 65, 66, 78, 94, 112, 131, 135, 163, 195, 197, 234, 262, 280,
               328, 337, 393, 404, 459, 485, 524, 582, 590, 655)
CEILING_DPS2, FLOOR_DPS2, TABLE_ACCEL_DPS2, TABLE_RATE_DPS = 450.0, 0.8, 1000.0, 1200.0


def campaign(samples: int) -> list[PlannedStep]:
    """All envelope-feasible steps of the five test groups."""
    steps = []
    for cycles in CYCLES_2_17:
        c = max(round(cycles * samples / 2**17), 1)
        f = c * FS_HZ / samples
        w = 2 * np.pi * f
        for group, accel in [("amp-0.2deg", 0.2 * w**2)] + [(f"accel-{a:g}", float(a))
                                                           for a in (1, 10, 100, 400)]:
            amp = accel / w**2
            if not (FLOOR_DPS2 <= accel <= min(CEILING_DPS2, TABLE_ACCEL_DPS2)
                    and amp * w <= TABLE_RATE_DPS):
                continue
            steps.append(PlannedStep(id=f"{group}-c{c}", kind="sine", axis="inner",
                                     samples=samples, duration_s=samples / FS_HZ,
                                     sample_rate_hz=FS_HZ, frequency_hz=f, cycles=c,
                                     amplitude_deg=amp, accel_dps2=accel, group=group,
                                     settle_s=5.0))
    return steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=2**17)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    steps = campaign(args.samples)
    t0 = time.perf_counter()
    data = simulate_dataset(realistic_rig_model(), steps, seed=args.seed)
    t_sim = time.perf_counter() - t0
    total = sum(len(s.table) for s in data.steps)
    timings, cpu = {}, {}
    outputs: dict[str, AnalysisOutput[object]] = {}
    for name in ("sync", "frf", "transfer_function"):  # each after what it requires
        plugin = plugins.load(name)
        ctx = AnalysisContext(options=plugin.options(),
                              upstream={r: outputs[r] for r in plugin.requires})
        t, c = time.perf_counter(), time.process_time()
        outputs[name] = plugin.cls().run(data, ctx)
        timings[name] = time.perf_counter() - t
        cpu[name] = time.process_time() - c
    elapsed, cpu_total = sum(timings.values()), sum(cpu.values())
    print(f"campaign: {len(steps)} steps × {args.samples} samples = {total} table samples "
          f"(simulated in {t_sim:.1f} s)")
    for key, t in timings.items():
        print(f"  {key:<18} {t:7.2f} s wall  {cpu[key]:7.2f} s CPU")
    print(f"analysis total {elapsed:.2f} s wall → {total / elapsed:,.0f} samples analysed per "
          f"second ({total / cpu_total:,.0f} per CPU-second; wall time suffers on a busy machine)")


if __name__ == "__main__":
    main()
