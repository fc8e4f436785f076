"""The re-analysis chain: an edit, a re-hash or a removal in SQL shows in ``ledger.check``."""

from __future__ import annotations

from sqlalchemy import text

from aatest.batch import ledger
from aatest.records.store import RecordStore


def _row(subject: str) -> dict[str, object]:
    return {"subject": subject, "record_id": None, "recording": f"/{subject}/recording.mcap",
            "mode": "analyze", "method_hash": "m" * 64, "method": {"mode": "analyze"},
            "aatest_version": "0", "overall_verdict": "pass", "verdicts": [],
            "quantities": {"scale_factor.v_sz": {"value": 0.004, "expanded_uncertainty": 1e-6,
                                                 "unit": "V/(°/s²)"}}, "outcome": {}}


def test_rows_are_unique_per_method_and_chained(empty_store_url: str) -> None:
    with RecordStore.open(empty_store_url) as store:
        first = ledger.append(store, _row("a"))
        assert ledger.append(store, _row("a")) is None  # (subject, method) stored once
        ledger.append(store, _row("b"))
        ledger.append(store, _row("c"))
        assert ledger.done_subjects(store, "m" * 64, ["a", "c", "z"]) == {"a", "c"}
        assert ledger.check(store) is None
        with store.engine.begin() as connection:
            connection.execute(text("UPDATE reanalyses SET overall_verdict = 'fail' "
                                    "WHERE id = :id"), {"id": first})
        assert ledger.check(store) == (f"re-analysis {first}: its content was edited after "
                                       "it was stored")
        with store.engine.begin() as connection:
            connection.execute(text("UPDATE reanalyses SET overall_verdict = 'pass'"))
            connection.execute(text("DELETE FROM reanalyses WHERE subject = 'b'"))
        broken = ledger.check(store)
        assert broken is not None and "link to the row before it is broken" in broken
