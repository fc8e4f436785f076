"""Every figure goes through ``aatest.presentation.figures``: no other module picks a backend
or saves a figure itself.

``matplotlib.use`` changes the backend of the whole process (an embedding application's
too), and a ``savefig`` elsewhere would bypass the reproducible, date-free SVG of
:func:`aatest.presentation.figures.to_svg`.
"""

from __future__ import annotations

import ast
from pathlib import Path

import aatest

SOURCE = Path(aatest.__file__).parent
HOME = SOURCE / "presentation" / "figures.py"


def _calls(path: Path) -> list[tuple[int, str]]:
    """(line, attribute) of every ``x.use(…)`` on matplotlib and every ``x.savefig(…)``."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            owner = node.func.value
            if node.func.attr == "savefig" or (
                    node.func.attr == "use" and isinstance(owner, ast.Name)
                    and owner.id in ("matplotlib", "mpl")):
                found.append((node.lineno, node.func.attr))
    return found


def test_only_the_figures_module_saves_or_picks_a_backend() -> None:
    offenders = {str(p.relative_to(SOURCE)): calls for p in sorted(SOURCE.rglob("*.py"))
                 if p != HOME and (calls := _calls(p))}
    assert offenders == {}
    assert [attr for _, attr in _calls(HOME)] == ["savefig"]
