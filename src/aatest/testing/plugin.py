"""The conformance kit as a pytest plugin: ``pytest --aatest-plugin turntable:NAME``.

Registered through the ``pytest11`` entry point, so installing aatest makes the option
available everywhere; without the option it does nothing. With it, pytest collects the
contract checks of :mod:`aatest.testing.conformance` (module
:mod:`aatest.testing.contract_checks`) for each named plugin, against the simulator the
plugin's package declares in the ``aatest.conformance`` entry-point group.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from aatest.testing import contract_checks


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("aatest", "aatest plugin conformance kit")
    group.addoption("--aatest-plugin", action="append", default=[], metavar="KIND:NAME",
                    help="check the contract of an installed aatest plugin against its "
                         "simulator (turntable:NAME, daq:NAME or chamber:NAME; repeatable)")


def pytest_configure(config: pytest.Config) -> None:
    if config.getoption("aatest_plugin"):
        path = str(Path(contract_checks.__file__))
        if path not in config.args:
            config.args.append(path)


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    if "aatest_spec" not in metafunc.fixturenames:
        return
    specs = metafunc.config.getoption("aatest_plugin")
    kind = getattr(metafunc.function, "kind", None)
    chosen = [s for s in specs if kind is None or s.startswith(f"{kind}:")]
    metafunc.parametrize("aatest_spec", chosen, ids=chosen)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Deselect the checks of kinds no ``--aatest-plugin`` names (they have no parameter),
    so a report lists only checks that ran."""
    if not config.getoption("aatest_plugin"):
        return
    unused = [item for item in items if "aatest_spec" in getattr(item, "fixturenames", ())
              and not isinstance(getattr(item, "callspec", None) and
                                 item.callspec.params.get("aatest_spec"), str)]  # type: ignore[attr-defined]
    if unused:
        config.hook.pytest_deselected(items=unused)
        items[:] = [item for item in items if item not in unused]
