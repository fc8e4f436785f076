"""sync plugins."""
