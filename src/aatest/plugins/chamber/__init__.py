"""chamber plugins."""
