"""Parsing of ACUTROL-class command lines: colon trees, short forms, ``;`` chaining.

A line holds one or more commands separated by ``;``. A command is a header and arguments:
``:DEMAND:POSITION 1,10.5``, ``:D:P 1,10.5`` and ``:d:pos 1 10.5`` are the same command (case
does not matter, every node may be shortened to any prefix that is unique among its siblings,
arguments are separated by commas or blanks). After a ``;``, a header without a leading colon
continues the previous command's branch, as in SCPI: ``:READ:POS? 1;RATE? 1`` reads position
and rate. ``*IDN?`` and the other IEEE-488.2 common commands stand alone. Sources: the
MIT-licensed AcutronicRobotics/acutrol driver (``:mode:position 1``, ``:demand:rate 1, 10``,
``:interlock:close 1``, ``:read:position 1``) and williamsea/Acutrol (``:M:P 1``, ``:D:O 1, a,
f, p``, ``:L :R P 1 v``, ``:I:C 1``, ``:R:P 1``, ``:u:f f ; :R:P 1``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: the command tree: node → children (leaves map to ``{}``)
TREE: dict[str, dict] = {
    "MODE": {"POSITION": {}, "RATE": {}, "ABSRATE": {}, "SYNTHESIS": {}, "OFF": {}},
    "DEMAND": {"POSITION": {}, "RATE": {}, "ACCELERATION": {}, "OSCILLATION": {}},
    "LIMIT": {"RATE": {}, "ACCELERATION": {}, "LOW": {}, "HIGH": {}, "VTRIP": {}},
    "INTERLOCK": {"OPEN": {}, "CLOSE": {}, "RESET": {}},
    "READ": {"POSITION": {}, "RATE": {}, "ACCELERATION": {}},
    "UTILITY": {"LOCKOUT": {}, "FORMAT": {}},
    "SYSTEM": {"ERROR": {}},
    # simulator-side convention (not in the public command set): the table log
    "XLOG": {"CONFIG": {}, "ARM": {}, "STATE": {}, "HEADER": {}, "DATA": {}, "MOUNTING": {}},
}


class CommandError(Exception):
    """A command the controller cannot parse or carry out; ``code`` is the SCPI error number."""

    def __init__(self, code: int, text: str) -> None:
        super().__init__(f"{code},\"{text}\"")
        self.code, self.text = code, text


@dataclass(frozen=True)
class Command:
    """One parsed command: its full path (long names), query flag and arguments."""

    path: tuple[str, ...]
    query: bool
    args: tuple[str, ...]

    @property
    def name(self) -> str:
        return ":" + ":".join(self.path) + ("?" if self.query else "")


def _resolve(token: str, siblings: dict[str, dict]) -> str:
    matches = [name for name in siblings if name.startswith(token)]
    if token in siblings:
        return token
    if len(matches) != 1:
        raise CommandError(-113, f"Undefined header {token}")
    return matches[0]


def _split_header(segment: str) -> tuple[str, str]:
    """``:D:P 1,2`` → (``:D:P``, ``1,2``); tolerates ``:L :R P 1 v`` (blank before a colon)."""
    text = segment.strip()
    position = 0
    while True:
        blank = text.find(" ", position)
        if blank < 0:
            return text, ""
        rest = text[blank:].lstrip()
        if not rest.startswith(":"):
            return text[:blank].replace(" ", ""), rest
        position = blank + 1


def parse_line(line: str) -> list[Command]:
    """All commands of ``line`` (raises :class:`CommandError` at the first bad one)."""
    commands: list[Command] = []
    branch: tuple[str, ...] = ()
    for raw in line.split(";"):
        if not raw.strip():
            continue
        header, arguments = _split_header(raw)
        header = header.upper()  # headers are case-insensitive; arguments keep their case
        args = tuple(a for a in arguments.replace(",", " ").split() if a)
        if header.startswith("*"):
            commands.append(Command((header.rstrip("?"),), header.endswith("?"), args))
            continue
        query = header.endswith("?")
        tokens = [t for t in header.rstrip("?").split(":") if t]
        if not tokens:
            raise CommandError(-102, "Syntax error")
        path = () if header.startswith(":") else branch
        node = TREE
        for part in path:
            node = node[part]
        resolved = list(path)
        for token in tokens:
            if not node:
                raise CommandError(-113, f"Undefined header {token}")
            name = _resolve(token, node)
            resolved.append(name)
            node = node[name]
        if node and not query:  # a query may stop at a branch (``:MODE? 1``)
            raise CommandError(-113, f"Incomplete header {header}")
        commands.append(Command(tuple(resolved), query, args))
        branch = tuple(resolved[:-1])
    return commands


def axis_of(command: Command) -> int:
    """The axis (first argument, 1 = inner, 2 = outer)."""
    if not command.args:
        raise CommandError(-109, f"Missing axis in {command.name}")
    if command.args[0] not in ("1", "2"):
        raise CommandError(-222, f"Axis {command.args[0]} out of range")
    return int(command.args[0])


def numbers(command: Command, count: int, start: int = 1) -> list[float]:
    """``count`` numeric arguments from ``start`` (after the axis)."""
    values = command.args[start:start + count]
    if len(values) < count:
        raise CommandError(-109, f"Missing parameter in {command.name}")
    try:
        result = [float(v) for v in values]
    except ValueError as exc:
        raise CommandError(-104, f"Data type error in {command.name}") from exc
    if not all(math.isfinite(v) for v in result):
        raise CommandError(-222, f"Data out of range in {command.name}")
    return result
