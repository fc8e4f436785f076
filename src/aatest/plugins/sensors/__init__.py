"""sensors plugins."""
