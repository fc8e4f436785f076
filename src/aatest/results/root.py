"""``RunResults``: the whole ``results.json`` (docs/interfaces.md §1) as one typed record.

The engine assembles it after the analysis pass; the uncertainty and verdict stages fill in
``verdicts``/``overall`` and the certified fields; the records store allocates the
``certificate_number`` before signing. Files written before the typed record (no
``schema_version``, no verdicts) still load: every later field has a default.
"""

from __future__ import annotations

from typing import Any

from pydantic import ConfigDict, Field, model_serializer, model_validator

from aatest.results._fields import Real
from aatest.results.base import Overall, ResultModel, Verdict
from aatest.results.bias import BiasResult
from aatest.results.frf import FrfResult
from aatest.results.misalignment import MisalignmentResult
from aatest.results.noise import DriftResult, NoiseResult
from aatest.results.reference import ReferenceResult
from aatest.results.scale_factor import ScaleFactorResult
from aatest.results.sync import SyncResult
from aatest.results.temperature import TemperatureResult
from aatest.results.transfer_function import TransferFunctionResult

#: version of the results.json layout written now; files without the field are version 1
SCHEMA_VERSION = 2


def _third_party_keys(schema: dict[str, Any]) -> None:
    """In the JSON the third-party results sit beside the built-in keys, not under ``extra``."""
    schema["properties"].pop("extra", None)
    schema["additionalProperties"] = True


class AnalysisBlock(ResultModel):
    """``results.analysis``: one optional field per built-in analysis key.

    Results of third-party analyses (entry-point group ``aatest.analyses``) live in ``extra``,
    each validated by its plugin's own ``Result`` model when the plugin runs; in the JSON they
    sit next to the built-in keys, as they always did.
    """

    model_config = ConfigDict(extra="forbid", validate_assignment=True,
                              json_schema_extra=_third_party_keys)

    sync: SyncResult | None = None
    reference: ReferenceResult | None = None
    bias: BiasResult | None = None
    scale_factor: ScaleFactorResult | None = None
    frf: FrfResult | None = None
    transfer_function: TransferFunctionResult | None = None
    temperature: TemperatureResult | None = None
    misalignment: MisalignmentResult | None = None
    noise: NoiseResult | None = None
    drift: DriftResult | None = None
    extra: dict[str, Any] = Field(default_factory=dict,
                                  description="key → result of a third-party analysis")

    @model_validator(mode="before")
    @classmethod
    def _collect_extra(cls, data: Any) -> Any:
        """Keys that are not built-in analyses go to ``extra`` (their plugin validates them)."""
        if not isinstance(data, dict):
            return data
        known = set(cls.model_fields)
        extra = dict(data.get("extra") or {})
        extra.update({k: v for k, v in data.items() if k not in known})
        return {k: v for k, v in data.items() if k in known and k != "extra"} | {"extra": extra}

    @model_serializer(mode="wrap")
    def _flatten(self, handler: Any) -> dict[str, Any]:
        """Built-in results that exist, then the third-party ones, all at one level."""
        dumped: dict[str, Any] = handler(self)
        extra = dumped.pop("extra", {}) or {}
        return {k: v for k, v in dumped.items() if v is not None} | extra

    def present(self) -> dict[str, Any]:
        """Key → typed result of every analysis that produced one (built-in and extra)."""
        built_in = {k: getattr(self, k) for k in type(self).model_fields if k != "extra"}
        return {k: v for k, v in built_in.items() if v is not None} | dict(self.extra)


class Signature(ResultModel):
    """Which key signed the bundle (the signature itself is a file next to the report)."""

    fingerprint: str


class RunResults(ResultModel):
    """The document between analysis and report: what was run, measured and decided."""

    schema_version: int = Field(1, description="results.json layout version")
    procedure: str
    rig: dict[str, Any] = Field(default_factory=dict, description="rig plugins and options")
    steps: list[dict[str, Any]] = Field(default_factory=list,
                                        description="each planned step plus sample counts")
    analysis: AnalysisBlock = Field(default_factory=AnalysisBlock)
    analysis_errors: dict[str, str] = Field(default_factory=dict)
    analysis_skipped: list[str] = Field(default_factory=list)
    lab_duration_s: Real = 0.0
    wall_duration_s: Real = 0.0
    metadata: dict[str, Any] = Field(default_factory=dict)
    figures: dict[str, dict[str, str]] = Field(default_factory=dict,
                                               description="analysis key → name → SVG")
    verdicts: list[Verdict] = Field(default_factory=list)
    overall: Overall = "none"
    certificate_number: str | None = None
    signature: Signature | None = None
