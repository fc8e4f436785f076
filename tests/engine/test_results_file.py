"""results.json: typed on the way in and out, NaN as null, old files still readable, third-party
results kept beside the built-in ones, and the schema check of the suite really checks."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import ClassVar

import pytest
from results_schema import assert_valid_results

from aatest.engine import registry
from aatest.engine.analysis import plugins
from aatest.engine.analysis.results_file import read_results, results_json, write_results
from aatest.engine.errors import InputError
from aatest.engine.interfaces import AnalysisOutput, NoOptions
from aatest.results import SCHEMA_VERSION, ResultModel, RunResults
from aatest.results.sync import SyncResult

SYNC = {"drift_ppm": -7.5, "offset_s": 0.0121, "residual_rms_us": 3.2, "edges_used": 400,
        "drift_u_ppm": 0.01, "drift_spread_ppm": 0.2,
        "steps": [{"step": "s001", "drift_ppm": -7.5, "offset_s": 0.0121,
                   "residual_rms_us": 3.2, "edges_used": 400}]}


def _results(**analysis: object) -> RunResults:
    return RunResults(schema_version=SCHEMA_VERSION, procedure="p", analysis=analysis)


def test_nan_is_written_as_null_and_read_back_as_nan(tmp_path: Path) -> None:
    results = _results(sync=SyncResult.model_validate(SYNC | {"drift_spread_ppm": math.nan}))
    write_results(results, tmp_path)
    doc = json.loads((tmp_path / "results.json").read_text(encoding="utf-8"))
    assert doc["analysis"]["sync"]["drift_spread_ppm"] is None
    back = read_results(tmp_path)
    assert back.analysis.sync is not None and math.isnan(back.analysis.sync.drift_spread_ppm)
    assert back.analysis.sync.steps[0].step == "s001"


def test_an_old_untyped_results_file_still_reads(tmp_path: Path) -> None:
    old = {"procedure": "p", "rig": {}, "steps": [], "analysis": {"sync": SYNC},
           "analysis_errors": {}, "analysis_skipped": [], "lab_duration_s": 1.0,
           "wall_duration_s": 2.0, "metadata": {}, "figures": {}}
    (tmp_path / "results.json").write_text(json.dumps(old), encoding="utf-8")
    back = read_results(tmp_path)
    assert back.schema_version == 1 and back.overall == "none" and back.verdicts == []
    assert back.certificate_number is None and back.analysis.sync is not None
    # the dump is a superset of what was read
    dumped = results_json(back)
    assert set(dumped) >= set(old) and dumped["analysis"]["sync"]["edges_used"] == 400


def test_third_party_results_sit_beside_the_built_in_ones(tmp_path: Path) -> None:
    results = _results(sync=SyncResult.model_validate(SYNC), vendor_drift={"ppm_per_c": 0.1})
    assert results.analysis.extra == {"vendor_drift": {"ppm_per_c": 0.1}}
    doc = results_json(results)
    assert set(doc["analysis"]) == {"sync", "vendor_drift"}
    write_results(results, tmp_path)
    assert read_results(tmp_path).analysis.extra == {"vendor_drift": {"ppm_per_c": 0.1}}
    assert assert_valid_results(tmp_path) == 1


def test_a_misspelt_key_is_refused(tmp_path: Path) -> None:
    doc = results_json(_results(sync=SyncResult.model_validate(SYNC)))
    doc["analysis"]["sync"]["drift_pmm"] = 1.0
    (tmp_path / "results.json").write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(InputError, match=r"analysis\.sync\.drift_pmm: Extra inputs"):
        read_results(tmp_path)
    with pytest.raises(AssertionError, match=r"violates results\.schema\.json"):
        assert_valid_results(tmp_path)
    (tmp_path / "results.json").unlink()  # keep the suite-wide check from seeing it again


class _VendorResult(ResultModel):
    ppm_per_c: float


class _VendorAnalysis:
    key: ClassVar[str] = "vendor_drift"
    requires: ClassVar[tuple[str, ...]] = ()
    Options: ClassVar[type[NoOptions]] = NoOptions
    Result: ClassVar[type[_VendorResult]] = _VendorResult

    def applies_to(self, data: object) -> bool:
        return True

    def run(self, data: object, context: object) -> AnalysisOutput[_VendorResult]:
        return AnalysisOutput(_VendorResult(ppm_per_c=0.1))


@pytest.fixture
def vendor_installed(monkeypatch: pytest.MonkeyPatch) -> None:
    """A third-party analysis 'installed' from a fake distribution."""
    real_load = registry.load

    def load(kind: str, name: str) -> registry.PluginInfo:
        if name == "vendor_drift":
            return registry.PluginInfo(kind, name, _VendorAnalysis, "vendor-dist", "2.0")
        return real_load(kind, name)

    monkeypatch.setattr(registry, "load", load)
    monkeypatch.setattr(plugins, "installed_names", lambda: ["sync", "vendor_drift"])


@pytest.mark.usefixtures("vendor_installed")
def test_third_party_results_are_typed_by_their_plugin_when_read(tmp_path: Path) -> None:
    write_results(_results(vendor_drift={"ppm_per_c": 0.1}), tmp_path)
    assert read_results(tmp_path).analysis.extra["vendor_drift"] == _VendorResult(ppm_per_c=0.1)
    write_results(_results(vendor_drift={"ppm": 0.1}), tmp_path)
    with pytest.raises(InputError, match=r"analysis\.vendor_drift: not a result of analysis "
                                         "plugin 'vendor_drift' from distribution 'vendor-dist'"):
        read_results(tmp_path)
