"""report plugins."""
