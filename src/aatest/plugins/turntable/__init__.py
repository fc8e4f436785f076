"""turntable plugins."""
