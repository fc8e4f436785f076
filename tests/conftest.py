"""Suite-wide settings: matplotlib without a display, seeded hypothesis."""

import os

os.environ.setdefault("MPLBACKEND", "Agg")
