"""Plugins, one sub-package per entry-point kind: ``turntable``, ``daq``, ``chamber``,
``sensors``, ``analysis`` and ``report``. The engine finds them through entry points only;
vendors add their own the same way (see ``docs/vendor-plugins.md``)."""
