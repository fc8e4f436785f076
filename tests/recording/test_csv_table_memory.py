"""The Arrow path of the CSV reader: exact values across Arrow's blocks, owned arrays, no pandas.

Why: a 45 MB import read through ``pyarrow``'s ``to_numpy`` imported pandas (≈ 50 MB resident
for nothing) and kept the parse buffers in Arrow's pool; the columns are now copied straight
out of Arrow's value buffers (``bench/diagnose.py`` measures the resident peak).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from aatest.recording.data import csv_table


def _write(path: Path, rows: int, seed: int) -> np.ndarray:
    """A plain numeric CSV of ``rows`` rows (time, two columns, one not wanted); its values."""
    rng = np.random.default_rng(seed)
    values = np.column_stack([np.arange(rows) * 5e-4, rng.standard_normal(rows),
                              rng.uniform(-1e6, 1e6, rows)])
    lines = ["time_s,a,unused"] + [f"{t!r},{a!r},{b!r}" for t, a, b in values.tolist()]
    path.write_text("\n".join(lines) + "\n")
    return values


def test_columns_span_arrow_blocks_exactly(tmp_path: Path) -> None:
    """A file of several Arrow parse blocks reads back bit for bit (repr round-trips floats),
    and every column owns its memory (the parsed table is released with the file)."""
    path = tmp_path / "big.csv"
    values = _write(path, 80_000, seed=7)
    assert path.stat().st_size > 3 * csv_table._BLOCK_BYTES  # several chunks per column
    got = csv_table.read_csv(path, ["time_s", "a"], ["unused"])
    for k, name in enumerate(("time_s", "a", "unused")):
        column = got.columns[name]
        assert column.dtype == np.float64 and column.flags.owndata
        assert not column.flags.writeable
        assert column.view(np.uint64).tolist() == values[:, k].view(np.uint64).tolist()
    assert got.row_lines[[0, -1]].tolist() == [2, 80_001]


def test_reading_a_csv_does_not_import_pandas(tmp_path: Path) -> None:
    """In a fresh interpreter, an import-directory CSV is read without importing pandas."""
    path = tmp_path / "x.csv"
    _write(path, 5_000, seed=3)
    code = ("import sys\n"
            "from pathlib import Path\n"
            "from aatest.recording.data.csv_table import read_csv\n"
            f"got = read_csv(Path({str(path)!r}), ['time_s', 'a'])\n"
            "assert len(got) == 5000\n"
            "print('pandas' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"
