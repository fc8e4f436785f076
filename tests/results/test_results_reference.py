"""results.json of each shipped procedure against a reference written by the dict-based engine.

The six files in ``data/reference/`` were produced by the engine before the typed record went
end to end (results built as a dict and read by string keys): each procedure's short variant in
``data/`` (same analyses, same report, fewer and shorter records) run on the digital twin with
``--seed 7``. Rerunning it now must give the same document: the same keys everywhere, the same
strings (after the changes made on purpose, :func:`documented_changes`), numbers within the
tolerances of ``tests/tolerances.py`` (``REFERENCE_RULES``). What legitimately differs run to
run is left out (:data:`VOLATILE`); figures are compared by name (their SVG is the analyses',
not this stage's).

Regenerate (only when a change of results is intended, and say so in the commit)::

    python tests/results/test_results_reference.py OUT_DIR [NAME ...]   # after running them
"""

from __future__ import annotations

import gzip
import json
import math
import re
import sys
from pathlib import Path
from typing import Any

import pytest
from tolerances import REFERENCE_RULES, tolerance

from aatest.engine.run.session import run
from aatest.numerics import K95, Z95
from aatest.results.quantities import reference_name

DATA = Path(__file__).parent / "data"
REFERENCE = DATA / "reference"
PROCEDURES = ("long-static-drift", "pivoted-misalignment", "scale-factor",
              "static-multi-position", "stepped-sine-frequency-response", "temperature-steps")
SEED = 7

#: keys whose values differ from run to run by design (time, place, who, the record number)
VOLATILE = {
    ("wall_duration_s",), ("certificate_number",), ("metadata", "started_utc"),
    ("metadata", "recording"), ("metadata", "operator"), ("metadata", "procedure_text"),
    ("metadata", "lab"),
    ("logged_temperature", "source"),  # the recording's path, where the run was written
}
#: numbers that are measured times, not results (the reference analysis times each method)
VOLATILE_LEAVES = re.compile(r".*\.runtime_s$")

#: keys the results gained on purpose since the references were written (documented in
#: docs/interfaces.md): a path pattern each; they may appear in the new document only
ADDITIONS: tuple[tuple[str, str], ...] = (
    (r"rig\.capabilities$", "the table plugin's declared capabilities (plugin contract)"),
    (r"metadata\.(kind|simulated_parts)$", "simulation marking: a twin run is a simulation"),
    (r"metadata\.rig\.capabilities$", "declared capabilities, as recorded with the run"),
    (r"analysis\.sync\.steps\[\d+\]\.(latched|slips_corrected|fit_coverage|"
     r"extrapolation_u_s|drift_source)$", "sync without latch times and on a partial table log"),
    (r"^verdicts\[\d+\]\.(limit_source|reason)$", "where a limit came from; why not judged"),
    (r"^analysis\.bias\.[^.]+\.(setpoints|temperature_c)$", "bias per chamber set-point"),
    (r"^logged_temperature$", "the logged temperatures, summarised for the certificate"),
    (r"^steps\[\d+\]\.daq_extremes$", "each sensor channel's extremes (logger-rail verdict)"),
)
#: the verdict added since on every run with a stated logger: checked apart (see the test)
RAILS = "samples_at_logger_rails"


#: budget rows whose basis now says where the encoder's number comes from — the rig file, the
#: table plugin's declaration, or a default naming the missing declaration (plugin contract,
#: docs/vendor-plugins.md): their wording changed on purpose, their numbers are compared
ENCODER_ROWS = frozenset({"encoder_accuracy", "encoder_resolution"})


def _without_encoder_basis(document: Any) -> Any:
    if isinstance(document, list):
        return [_without_encoder_basis(x) for x in document]
    if not isinstance(document, dict):
        return document
    return {k: _without_encoder_basis(v) for k, v in document.items()
            if not (k == "basis" and document.get("name") in ENCODER_ROWS)}


def _added(path: str) -> bool:
    return any(re.search(pattern, path) for pattern, _why in ADDITIONS)


def documented_changes(document: Any) -> Any:
    """The old document with the changes made on purpose since, applied the way they were:

    - the scale factor's ``scale_ci95`` is built with Z95 instead of K95 (its half-width
      × Z95/K95);
    - the reference-method budget row names the acceleration references as a person reads
      them (``central_position`` → ``central difference of the position``), so no
      implementation name reaches the certificate.
    """
    if isinstance(document, list):
        return [documented_changes(x) for x in document]
    if not isinstance(document, dict):
        return document
    out = {k: documented_changes(v) for k, v in document.items()}
    if out.get("name") in ENCODER_ROWS:
        out.pop("basis", None)
    if out.get("basis") == "measured: sync analysis offset_u_s of this record":
        out["basis"] = ("measured: the clock alignment's own standard uncertainty, from the "
                        "freeze-pulse latch times of this record")  # no field name for a person
    interval = out.get("scale_ci95")
    if isinstance(interval, list) and len(interval) == 2:  # a [lo, hi] pair
        # built as scale ± Z95·u since, the factor ci_std reads it back with (was K95 = 1.96)
        middle, half = (interval[0] + interval[1]) / 2, (interval[1] - interval[0]) / 2
        out["scale_ci95"] = [middle - half * Z95 / K95, middle + half * Z95 / K95]
    if out.get("name") == "reference_method" and "basis" in out:
        out["label"] = re.sub(r"\((\w+)\)$", lambda m: f"({reference_name(m.group(1))})",
                              out["label"])
        out["quantity"] = out["label"]
        out["basis"] = re.sub(r"\((\w+) vs (\w+)\)", lambda m: f"({reference_name(m.group(1))}"
                              f" vs {reference_name(m.group(2))})", out["basis"])
    return out


def comparable(document: dict[str, Any]) -> dict[str, Any]:
    """The document without its volatile keys, with each figure reduced to its name."""
    out = json.loads(json.dumps(document))
    for path in VOLATILE:
        parent = out
        for key in path[:-1]:
            parent = parent.get(key, {})
        parent.pop(path[-1], None)
    for answer in out.get("metadata", {}).get("prompt_answers", []):
        answer.pop("answered_utc", None)  # when the run happened
    out["figures"] = {k: sorted(v) for k, v in out.get("figures", {}).items()}
    return dict(_without_encoder_basis(out))


def _number_differs(before: float, after: float, path: str) -> list[str]:
    rule = tolerance(path, REFERENCE_RULES)
    rel, abs_ = rule.rel, rule.abs
    if VOLATILE_LEAVES.match(path) or math.isclose(before, after, rel_tol=rel, abs_tol=abs_):
        return []
    return [f"{path}: {before!r} became {after!r} (rel {rel:g}, abs {abs_:g})"]


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def differences(before: Any, after: Any, path: str = "") -> list[str]:
    """Every place the two documents differ beyond the tolerances, as readable lines."""
    if isinstance(before, dict) and isinstance(after, dict):
        lost = sorted(before.keys() - after.keys())
        extra = sorted(k for k in after.keys() - before.keys()
                       if not _added(f"{path}.{k}".lstrip(".")))
        if lost or extra:
            return [f"{path}: keys lost {lost}, added without documentation {extra}"]
        return [d for k in before
                for d in differences(before[k], after[k], f"{path}.{k}".lstrip("."))]
    if isinstance(before, list) and isinstance(after, list):
        if len(before) != len(after):
            return [f"{path}: {len(before)} items became {len(after)}"]
        return [d for i, (b, a) in enumerate(zip(before, after, strict=True))
                for d in differences(b, a, f"{path}[{i}]")]
    if _is_number(before) and _is_number(after):
        return _number_differs(before, after, path)
    return [] if before == after else [f"{path}: {before!r} became {after!r}"]


@pytest.mark.parametrize("name", PROCEDURES, ids=PROCEDURES)
def test_results_json_matches_the_reference(name: str, tmp_path: Path) -> None:
    run_dir, _ = run(DATA / f"{name}.yaml", None, tmp_path / name, False, SEED, None,
                     show_progress=False, operator="reference", confirm_prompts="auto")
    after = comparable(json.loads((run_dir / "results.json").read_text()))
    rails = [v for v in after["verdicts"] if v["quantity"] == RAILS]
    after["verdicts"] = [v for v in after["verdicts"] if v["quantity"] != RAILS]
    # the twin's sensors span 0.2…4.8 V, inside its logger's ±10 V: one passing rail verdict
    # per sensor channel, with no sample at a rail
    assert {v["channel"] for v in rails} == {s["channel"] for s in after["metadata"]["sensors"]}
    assert all(v["value"] == 0 and v["verdict"] == "pass" for v in rails), rails
    with gzip.open(REFERENCE / f"{name}.json.gz", "rt") as f:
        before = documented_changes(json.load(f))
    found = differences(before, after)
    assert not found, "\n".join(found[:20])


def _write_references(runs: Path, names: tuple[str, ...] = PROCEDURES) -> None:
    """Write the reference of each procedure named from ``runs/<name>/results.json``."""
    REFERENCE.mkdir(exist_ok=True)
    for name in names:
        document = comparable(json.loads((runs / name / "results.json").read_text()))
        text = json.dumps(document, separators=(",", ":"), sort_keys=False)
        with gzip.GzipFile(REFERENCE / f"{name}.json.gz", "wb", mtime=0) as f:
            f.write(text.encode())


if __name__ == "__main__":
    _write_references(Path(sys.argv[1]), tuple(sys.argv[2:]) or PROCEDURES)
