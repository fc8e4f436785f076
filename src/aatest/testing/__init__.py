"""Test tools for plugin authors: the conformance kit (a pytest plugin, ``pytest
--aatest-plugin turntable:NAME``) and transcript tests that pin a driver's wire exchange
(:mod:`aatest.testing.transcript`)."""
