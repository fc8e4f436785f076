"""analysis plugins."""
