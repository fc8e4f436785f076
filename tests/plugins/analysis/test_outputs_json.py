"""Every analysis returns JSON-serialisable values and SVG figures on a mixed recording."""

from __future__ import annotations

import json

from aatest.engine.interfaces import Analysis, AnalysisContext
from aatest.plugins.analysis import ALIASES
from aatest.plugins.analysis.bias import BiasAnalysis
from aatest.plugins.analysis.frf import FrfAnalysis
from aatest.plugins.analysis.noise import NoiseAnalysis
from aatest.plugins.analysis.reference import ReferenceAnalysis
from aatest.plugins.analysis.scale_factor import ScaleFactorAnalysis
from aatest.plugins.analysis.temperature import TemperatureAnalysis
from aatest.plugins.analysis.transfer_function import TransferFunctionAnalysis
from aatest.plugins.analysis.sync import SyncAnalysis
from synthetic_rig import SynthRig, make_dataset, sine_step, static_step


def test_all_analyses_json_and_protocol() -> None:
    steps = [sine_step(f"s{c}", c, 100.0, samples=8192) for c in (2, 4, 8, 16, 24, 32, 41)]
    steps += [static_step(f"t{i}", 0, o, samples=4096, temperature_c=t)
              for i, (o, t) in enumerate([(0, 20.0), (180, 0.0), (0, -10.0), (180, 30.0)])]
    data = make_dataset(steps, SynthRig())
    ctx = AnalysisContext()
    plugins = [SyncAnalysis(), ReferenceAnalysis(), ScaleFactorAnalysis(), FrfAnalysis(),
               TransferFunctionAnalysis(), BiasAnalysis(), TemperatureAnalysis(),
               NoiseAnalysis()]
    for plugin in plugins:
        assert isinstance(plugin, Analysis)
        assert plugin.applies_to(data), plugin.key
        out = plugin.run(data, ctx)
        json.dumps(out.values, allow_nan=True)
        assert all(svg.lstrip().startswith("<?xml") for svg in out.figures.values())
    assert ALIASES == {"thd": "frf", "snr": "frf"}
