"""daq plugins."""
