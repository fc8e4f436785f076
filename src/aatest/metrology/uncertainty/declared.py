"""Where the encoder's numbers in a budget come from: no silent defaults.

Each encoder number (resolution, accuracy) comes, in this order, from the rig description
(``instruments.encoder``: the lab's own statement, with its certificate), from the turntable
plugin's declaration (``capabilities()``, recorded with the run under
``metadata.rig.capabilities.turntable``), or from a stated default — and a row built on a
default names the declaration that is missing, so a 24-bit encoder (0.077″ per count) is
never budgeted as the documented rig's 0.01″ without the certificate saying so.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

from aatest.engine.rig_description import Instruments
from aatest.results import RunResults

#: encoder field of the rig description → the capability a turntable plugin declares
ENCODER_DECLARATIONS: dict[str, str] = {
    "resolution_counts_per_rev": "encoder_resolution_counts_per_rev",
    "accuracy_arcsec": "encoder_accuracy_arcsec",
}
#: the same declarations in words, as a certificate names them (no field names on a page)
_DECLARATION_NAMES: dict[str, str] = {
    "resolution_counts_per_rev": "encoder resolution",
    "accuracy_arcsec": "encoder accuracy",
}

#: per encoder field: ("declared" | "default", the sentence that says by whom / what is missing)
Basis = dict[str, tuple[Literal["declared", "default"], str]]


def _table_declaration(results: RunResults) -> Mapping[str, Any]:
    """``rig.capabilities.turntable`` as recorded with the run (empty: none recorded).

    The rig block is the user's free-form rig description plus the declarations the engine
    recorded beside it, so it stays a mapping here.
    """
    for rig in (results.metadata.recorded("rig"), results.rig):
        if isinstance(rig, Mapping):
            table = (rig.get("capabilities") or {}).get("turntable")
            if isinstance(table, Mapping):
                return table
    return {}


def declared_encoder(results: RunResults, stated: Mapping[str, Any] | None,
                     instruments: Instruments) -> tuple[Instruments, Basis]:
    """The instruments with the plugin's declared encoder where the rig description states
    none (``stated``: its ``instruments`` block, None without one), and for every encoder
    number not from the rig description, its basis."""
    stated = stated or {}
    encoder_block = stated.get("encoder")
    stated_encoder: Mapping[str, Any] = encoder_block if isinstance(encoder_block, Mapping) else {}
    table = _table_declaration(results)
    plugin, declared = table.get("plugin"), table.get("declared") or {}
    who = f"turntable plugin '{plugin}'" + (f" ({table['distribution']})"
                                            if table.get("distribution") else "")
    updates: dict[str, Any] = {}
    basis: Basis = {}
    for field, capability in ENCODER_DECLARATIONS.items():
        if field in stated_encoder:
            continue  # the lab's own statement stands
        value = declared.get(capability) if isinstance(declared, Mapping) else None
        if value is not None:
            updates[field] = value
            basis[field] = ("declared", f"declared by the {who}")
            continue
        label = _DECLARATION_NAMES[field]
        missing = (f"the {who} declares no {label}" if plugin
                   else "no turntable plugin declared it (no run behind these data)")
        basis[field] = ("default", f"missing declaration: {missing}, and the rig description "
                                   f"states no {label}")
    if not updates:
        return instruments, basis
    encoder = instruments.encoder.model_copy(update=updates)
    return instruments.model_copy(update={"encoder": encoder}), basis
