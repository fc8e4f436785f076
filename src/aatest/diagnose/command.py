"""``aatest diagnose DATA [--json-out FILE] [--model-out FILE]`` (docs/interfaces.md §4).

Reads a run directory, a recording or an import directory, runs the diagnose pipeline, prints
a short summary, writes the JSON and the extended model, and renders the diagnosis report
through the ``diagnosis`` report plugin when it is installed (its absence never breaks
diagnose). Returns the findings and the unexplained structure (what the nominal model gets
wrong, named or not); the CLI exits 1 when there is any, 0 otherwise.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from aatest.diagnose.model_out import extended_model, write_model
from aatest.diagnose.pipeline import diagnose_dataset
from aatest.engine import registry
from aatest.parallel.gc_freeze import older_objects_frozen
from aatest.storage import Where, locate


def _clean(value: Any) -> Any:
    """JSON-safe copy: NaN/inf become null, numpy scalars plain numbers."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def summary(doc: dict[str, Any]) -> str:
    """A few lines a person reads first."""
    gain = doc["gain"]
    lines = [f"baseline residual {1e3 * doc['baseline']['rmse_v']:.3f} mV RMS (held-out)"]
    floor = doc.get("noise_floor")
    if floor:
        lines.append(f"noise floor {1e3 * floor['rms_v']:.3f} mV RMS, read from the data: "
                     f"{floor['method']}; residual after the model {floor['ratio']:.2f}× it "
                     f"(explained up to {floor['explained_ratio']:g}×)")
    lines.append(doc["verdict"]["headline"])
    for f in doc["findings"]:
        params = ", ".join(f"{k}={v:.4g}" for k, v in f["parameters"].items())
        lines.append(f"finding {f['effect']} ({f.get('attributed_to', 'sensor')}, "
                     f"{f.get('channel', '')}): {params}; ΔBIC {f['evidence']['delta_bic']:.1f}")
    for u in doc.get("unexplained", []):
        lines.append(f"unexplained {u['kind']} ({u.get('channel', '')}): {u['description']}; "
                     f"ΔBIC {u['evidence']['delta_bic']:.1f}")
    if doc.get("steps_skipped"):
        lines.append("steps left out (no sync edges, no trigger): "
                     + ", ".join(doc["steps_skipped"]))
    if doc.get("steps_clipped"):
        clipped = [f"{step} ({', '.join(f'{ch}: {n} samples' for ch, n in at.items())})"
                   for step, at in doc["steps_clipped"].items()]
        lines.append("steps left out (the logger clipped them: samples at the rails of its "
                     "input range): " + ", ".join(clipped))
    for c in doc["candidates"]:
        if not c.get("accepted") and c.get("delta_bic") is not None and c["delta_bic"] < 0:
            lines.append(f"not accepted {c['effect']} ({c.get('channel', '')}): ΔBIC "
                         f"{c['delta_bic']:.1f}; {c.get('reason', '')}")
    untestable = [c["effect"] for c in doc["candidates"] if c.get("testable") is False]
    if untestable:
        lines.append("not testable with these data: " + ", ".join(sorted(set(untestable))))
    lines.append(f"gain: {1e3 * gain['rmse_v_before']:.3f} → {1e3 * gain['rmse_v_after']:.3f} mV "
                 f"({gain['reduction_pct']:.1f} % lower)")
    if doc.get("unexplained"):
        named = doc["gain_named"]
        lines.append(f"gain of the named effects alone: {1e3 * named['rmse_v_after']:.3f} mV "
                     f"({named['reduction_pct']:.1f} % lower)")
    return "\n".join(lines)


def _render_report(doc: dict[str, Any], figures: dict[str, str], out_dir: Where) -> None:
    """Render the diagnosis report when the plugin exists; never fail diagnose over it
    (a run on object storage gets it rendered locally and uploaded beside the recording)."""
    from aatest.storage import staged

    try:

        info = registry.load("report", "diagnosis")
        cls = info.target
        results = {"diagnosis": doc, **doc, "figures": {"diagnose": figures}}
        with staged(out_dir) as local_dir:
            cls(cls.Config()).render(results, local_dir, None)
    except Exception:  # noqa: BLE001 - the report is a by-product of diagnose
        return


@registry.pinned()  # the installed plugins (effects) are read once per diagnosis
def diagnose_command(data: Where | str, json_out: Path | None,
                     model_out: Path | None) -> list[dict]:
    """Diagnose ``data``; write JSON / model / report.

    Returns
    -------
    list of dict
        The findings, then the ``unexplained`` entries (contract dicts): empty when the
        nominal model explains the data.
    """
    with older_objects_frozen():  # aatest.parallel.gc_freeze says why
        # a path, or a URL whose recording is streamed (docs/storage.md)
        return _diagnose(locate(data), json_out, model_out)


def _return_freed_heap() -> None:
    """Give the heap memory freed so far back to the system (glibc's ``malloc_trim``; a no-op
    where there is none).

    Why: an import directory is parsed by reader threads, and glibc keeps what each thread
    freed in that thread's own arena, where the diagnosis (on the main thread) never reuses
    it: 24 MB of the 16-step dataset's peak resident memory, measured.
    """
    import ctypes

    try:
        trim = ctypes.CDLL(None).malloc_trim  # the process's own symbols: libc's, if glibc
    except (OSError, AttributeError):
        return
    trim(0)


def _diagnose(data: Where, json_out: Path | None, model_out: Path | None) -> list[dict]:
    """The body of :func:`diagnose_command` on a located ``data``."""
    from aatest.recording import read_dataset

    dataset = read_dataset(data)
    _return_freed_heap()
    figures: dict[str, str] = {}
    doc = _clean(diagnose_dataset(dataset, figures=figures))
    print(summary(doc))
    if json_out is not None:
        Path(json_out).write_text(json.dumps(doc, indent=1), encoding="utf-8")
    if model_out is not None:
        model = extended_model(doc["channels"], doc["findings"], doc["logger"]["antialias_hz"],
                               doc["logger"]["t_ref_c"])
        write_model(Path(model_out), model)
    out_dir: Where = Path(json_out).parent if json_out is not None else data
    if out_dir.is_dir():
        _render_report(doc, figures, out_dir)
    return list(doc["findings"]) + list(doc["unexplained"])
