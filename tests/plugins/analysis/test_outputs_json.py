"""Every analysis returns its typed result (JSON-serialisable) and SVG figures on a mixed
recording, and every plugin class satisfies the Analysis protocol and the engine's checks."""

from __future__ import annotations

import json

from synthetic_rig import SynthRig, make_dataset, sine_step, static_step

from aatest.engine.analysis import plugins
from aatest.engine.analysis.passes import run_analyses
from aatest.engine.analysis.plugins import aliases
from aatest.engine.interfaces import Analysis
from aatest.results import AnalysisBlock


def test_all_analyses_json_and_protocol() -> None:
    steps = [sine_step(f"s{c}", c, 100.0, samples=8192) for c in (2, 4, 8, 16, 24, 32, 41)]
    steps += [static_step(f"t{i}", 0, o, samples=4096, temperature_c=t)
              for i, (o, t) in enumerate([(0, 20.0), (180, 0.0), (0, -10.0), (180, 30.0)])]
    data = make_dataset(steps, SynthRig())
    names = ["sync", "reference", "scale_factor", "frf", "transfer_function", "bias",
             "temperature", "noise"]
    for name in names:
        plugin = plugins.load(name)
        assert isinstance(plugin.cls(), Analysis)
        assert plugin.cls().applies_to(data), name
    done = run_analyses(data, names)
    assert done.errors == {} and set(done.outputs) == set(names)
    for key, out in done.outputs.items():
        assert isinstance(out.result, plugins.load(key).cls.Result)
        assert all(svg.lstrip().startswith("<?xml") for svg in out.figures.values())
    block = AnalysisBlock.model_validate(done.values)
    json.dumps(block.model_dump(mode="json"), allow_nan=False)
    assert aliases() == {"thd": "frf", "snr": "frf"}
