"""Benchmark the transfer-function analysis alone: the model fits of every sensor and group.

The analysis tail of the stepped sine (:func:`aatest.plugins.analysis.transfer_function.
sensor_models`: every group's candidate scan and second-order-plus-delay fit, on the analysis
pass's forked workers, and its Bode figure, drawn here in place where ``aatest run`` draws it
aside) runs after the record phase when the fits were not made while the run recorded. Its
inputs — the FRF points, the groups' cross-correlations, the sensors and options — are
captured once from a recorded run (sync and frf analysed as
``aatest analyze`` does), then ``sensor_models`` is timed on them in fresh processes,
alternately on another checkout's ``src`` (first on ``PYTHONPATH``) and on this one, with the
default workers and with one (``AATEST_WORKERS=1``: the CPU of the fits alone). It prints the
median wall and CPU seconds (CPU counts the forked workers) and their ratios, and compares the
two checkouts' results: the largest change of any number (relative to the number and, for
the second-order fit, to its stated uncertainty) and whether the figures are the same bytes.

    python bench/tf_fits.py RUN_DIR --compare BASE/src [--rounds 3]
    python bench/tf_fits.py RUN_DIR            # this checkout only

``--inputs FILE`` keeps the captured inputs (read when the file exists: repeated comparisons
skip the analysis of the run).

RUN_DIR is a kept stepped-sine run (``python bench/end_to_end.py --seed 7 --dir RUN_DIR``).
"""

from __future__ import annotations

import argparse
import math
import os
import pickle
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from child_run import child_json, leaves  # bench/ (the script's directory) is on sys.path

#: the captured inputs: sensor_models' arguments, the steps reduced to their planned steps and
#: each group's cross-correlation by (channel, step ids)
Inputs = dict[str, Any]


def _cpu_s() -> float:
    own, children = (resource.getrusage(who)
                     for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def capture(run_dir: Path) -> Inputs:
    """Analyse ``run_dir`` with sync, frf and transfer_function, keeping what
    ``sensor_models`` was given (its steps as planned steps, their correlations computed)."""
    import aatest.plugins.analysis.transfer_function as tf
    from aatest.engine.analysis.passes import run_analyses
    from aatest.recording import read_dataset

    kept: Inputs = {"xcorr": {}}
    real_models, real_xcorr = tf.sensor_models, tf.rated_xcorr

    def xcorr(steps: Any, sensor: Any) -> Any:
        value = real_xcorr(steps, sensor)
        kept["xcorr"][sensor.channel, tuple(p.id for p in _planned(steps))] = value
        return value

    def models(points: Any, steps: Any, sensors: Any, antialias_hz: Any, options: Any,
               *ready: Any) -> Any:
        # the fits the early-analysis child made (``ready``) are left out: every fit is timed
        kept.update(points=dict(points), planned=list(_planned(steps)), sensors=list(sensors),
                    antialias_hz=antialias_hz, options=options)
        return real_models(points, steps, sensors, antialias_hz, options, *ready)

    tf.sensor_models, tf.rated_xcorr = models, xcorr
    try:
        data = read_dataset(run_dir)
        out = run_analyses(data, ["sync", "frf", "transfer_function"])
    finally:
        tf.sensor_models, tf.rated_xcorr = real_models, real_xcorr
    if "transfer_function" in out.errors or "points" not in kept:
        raise SystemExit(f"{run_dir}: no transfer function analysed ({out.errors})")
    return kept


def _planned(steps: Any) -> Any:
    return steps.planned if hasattr(steps, "planned") else [s.step for s in steps]


def run_once(inputs: Inputs) -> tuple[float, float, Any]:
    """Wall and CPU seconds of one ``sensor_models`` on the captured inputs, and its output."""
    from threadpoolctl import threadpool_limits

    import aatest.plugins.analysis.transfer_function as tf

    _warm_matplotlib()
    table = inputs["xcorr"]
    tf.rated_xcorr = lambda steps, sensor: table[sensor.channel,
                                                 tuple(s.step.id for s in steps)]
    steps = [SimpleNamespace(step=p) for p in inputs["planned"]]
    with threadpool_limits(limits=1, user_api="blas"):  # as the analysis pass runs
        wall, cpu = time.perf_counter(), _cpu_s()
        out = tf.sensor_models(inputs["points"], steps, inputs["sensors"],
                               inputs["antialias_hz"], inputs["options"])
        return time.perf_counter() - wall, _cpu_s() - cpu, _drawn(out)


def _drawn(out: Any) -> Any:
    """``sensor_models``' output with each figure as its SVG (a checkout whose figures are
    :func:`aatest.presentation.figures.drawn` returns them as results to be taken; outside a
    drawing-aside block they were drawn in place, inside the timing)."""
    def svg(figure: Any) -> Any:
        return figure.result() if hasattr(figure, "result") else figure

    return {channel: (row, {name: svg(f) for name, f in figures.items()})
            for channel, (row, figures) in out.items()}


def _warm_matplotlib() -> None:
    """Draw a small figure, as the frf analysis has drawn its own before this one runs in
    an analysis pass (matplotlib imported, its fonts loaded, in the process that forks)."""
    from aatest.presentation.figures import new_figure, to_svg

    fig, ax = new_figure(1)
    ax[0, 0].semilogx([1.0, 10.0], [1.0, 2.0], "o-", label="warm")
    ax[0, 0].set(title="warm", xlabel="f", ylabel="g")
    ax[0, 0].legend(fontsize=6)
    fig.tight_layout()
    to_svg(fig)


def _numbers(value: Any) -> dict[str, float]:
    """Every number of a (nested) result by its path."""
    return {path: float(leaf) for path, leaf in leaves(value)
            if isinstance(leaf, int | float) and not isinstance(leaf, bool)}


def differences(base: Any, this: Any) -> list[str]:
    """What differs between two outputs of ``sensor_models``: the largest relative change of
    any number, the second-order fit's against its stated uncertainty, figures, structure."""
    lines = []
    nb, nt = _numbers(base), _numbers(this)
    if nb.keys() != nt.keys():
        differ = ", ".join(sorted(nb.keys() ^ nt.keys()))
        return [f"the outputs differ in structure: {differ[:400]}"]
    rel = {k: abs(nt[k] - nb[k]) / abs(nb[k]) for k in nb
           if nb[k] != nt[k] and math.isfinite(nb[k]) and nb[k] != 0}
    odd = [k for k in nb if nb[k] != nt[k] and not (math.isnan(nb[k]) and math.isnan(nt[k]))
           and k not in rel]
    changed = sum(nb[k] != nt[k] for k in nb if not (math.isnan(nb[k]) and math.isnan(nt[k])))
    lines.append(f"{changed} of {len(nb)} numbers differ"
                 + (f"; largest relative change {max(rel.values()):.2e} at {max(rel, key=rel.get)}"
                    if rel else "") + (f"; not comparable: {odd[:5]}" if odd else ""))
    worst = 0.0
    for key in nb:
        head, _, name = key.rpartition(".")
        u_key = f"{head}.u_{name}"
        if u_key in nb and nb[u_key] and "second_order_delay" in key:
            worst = max(worst, abs(nt[key] - nb[key]) / nb[u_key])
    lines.append(f"second-order fit: largest change {worst:.2e} of its stated uncertainty")
    figures_b = {k: svg for _, (_, figs) in sorted(base.items()) for k, svg in figs.items()}
    figures_t = {k: svg for _, (_, figs) in sorted(this.items()) for k, svg in figs.items()}
    same = sum(figures_b.get(k) == svg for k, svg in figures_t.items())
    lines.append(f"figures: {same} of {len(figures_t)} the same bytes "
                 f"(base has {len(figures_b)})")
    return lines


def compare(run_dir: Path, base_src: Path, rounds: int, kept: Path | None) -> None:
    this_src = Path(__file__).resolve().parents[1] / "src"
    with tempfile.TemporaryDirectory(prefix="aatest-bench-tf-") as tmp:
        inputs = kept or Path(tmp) / "inputs.pkl"
        if not inputs.exists():
            inputs.write_bytes(pickle.dumps(capture(run_dir)))
        rows: dict[tuple[str, str], list[tuple[float, float]]] = {}
        outputs = {}
        for i in range(rounds):
            for workers in ("default", "1"):
                for label, src in (("base", base_src), ("this", this_src)):
                    out = Path(tmp) / f"{label}.pkl"
                    doc = child_json(__file__, src, [str(run_dir), "--time", str(inputs),
                                                     "--workers", workers, "--out", str(out)],
                                     "tf bench")
                    rows.setdefault((label, workers), []).append((doc["wall"], doc["cpu"]))
                    outputs[label] = pickle.loads(out.read_bytes())
                    print(f"round {i + 1} {label} workers={workers}: {doc['wall']:.2f} s wall, "
                          f"{doc['cpu']:.2f} s CPU; load {os.getloadavg()[0]:.1f}", flush=True)
    print(f"median of {rounds} rounds, sensor_models on {run_dir}: base {base_src} vs this")
    print(f"  {'workers':<8} {'base wall':>10} {'this wall':>10} {'ratio':>6} "
          f"{'base CPU':>9} {'this CPU':>9} {'ratio':>6}")
    for workers in ("default", "1"):
        bw, bc = (statistics.median(r[c] for r in rows["base", workers]) for c in (0, 1))
        tw, tc = (statistics.median(r[c] for r in rows["this", workers]) for c in (0, 1))
        print(f"  {workers:<8} {bw:10.2f} {tw:10.2f} {bw / tw:6.2f} {bc:9.2f} {tc:9.2f} "
              f"{bc / tc:6.2f}")
    for line in differences(outputs["base"], outputs["this"]):
        print("results: " + line)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--compare", type=Path, default=None, metavar="BASE_SRC")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--inputs", type=Path, default=None,
                        help="the captured inputs: read when this file exists, else kept here")
    parser.add_argument("--time", type=Path, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--workers", default="default", help=argparse.SUPPRESS)
    parser.add_argument("--out", type=Path, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.compare is not None:
        compare(args.run_dir, args.compare.resolve(), args.rounds, args.inputs)
        return
    if args.workers != "default":
        os.environ["AATEST_WORKERS"] = args.workers
    inputs = (pickle.loads(args.time.read_bytes()) if args.time is not None
              else capture(args.run_dir))
    wall, cpu, out = run_once(inputs)
    if args.out is not None:
        args.out.write_bytes(pickle.dumps(out))
        print(f'{{"wall": {wall}, "cpu": {cpu}}}')
        return
    print(f"sensor_models: {wall:.2f} s wall, {cpu:.2f} s CPU", file=sys.stderr)


if __name__ == "__main__":
    main()
