"""Orchestration: procedure models, loading, planning, plugin registry, runner, recording."""
