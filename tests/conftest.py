"""Suite-wide settings: matplotlib without a display, seeded hypothesis."""

import os
import tempfile

os.environ.setdefault("MPLBACKEND", "Agg")
# CLI runs register calibration records: never into the user's own store (tests/records
# points each of its tests at a fresh one)
os.environ.setdefault("AATEST_RECORDS", "sqlite:///" + os.path.join(
    tempfile.mkdtemp(prefix="aatest-test-records-"), "records.sqlite"))
