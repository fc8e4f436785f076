"""Per-step design columns and Gram blocks, each kept under what it depends on.

A diagnosis fits hundreds of specs on one channel, most of them one shape parameter away from
the model before (a delay search, a saturation search, the joint polish of the shapes). A
design column depends on a few of the shape parameters only — the bias on none, the
temperature and gravity terms on none, the jerk pickup on the timing and the hysteresis but
not the dynamics or clipping, the vibration and ripple terms on the timing and the dynamics
but not on hysteresis or clipping, the scale column on the whole sensor chain. So each
column is keyed by what it depends on (:func:`column_key`), and a step's Gram block under a
new shape starts from the block it was last seen under: the rows and columns of XᵀX whose
column keys are unchanged are copied, and only the changed columns are built and multiplied
(O(n·p·q) for q changed of p columns, instead of building all p columns through the logger
filter and forming O(n·p²) products).

A vibration tone read from the filters' frequency response is the pair Re, Im of
gain·e^{iθ}: its sine and cosine on the record grid (which depend on the clock warp only)
turned and scaled by one complex gain (which holds the delay and the dynamics). The block keeps
the Gram entries of the sine and cosine themselves, and :func:`gram` turns them by each tone's
gain (a 2×2 rotation per tone): a delay, dynamics or polish search then copies every tone's
entries and builds and multiplies only the columns of the sensor chain (a five-tone band is
ten of a step's thirteen columns).

The columns themselves are held under a byte budget (least recently used released first) and
rebuilt from the replay when a released one is needed again; the Gram entries (a few numbers
per pair) are always kept.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from aatest.diagnose.design import (
    Replay,
    _design,
    _step_key,
    column_names,
    eval_step_s,
    inner_projection,
    step_damped,
    tone_basis_row,
    tone_gain,
)
from aatest.diagnose.gram import Fit, Gram, block_edges, fit_gram, fold_products
from aatest.diagnose.replay import StepReplay
from aatest.diagnose.spec import ChannelInfo, Spec

#: key of the column-memory budget inside a gram cache
BUDGET_KEY = "design column budget"
#: bytes of design columns kept per channel for re-use (Gram blocks are always kept)
COLUMN_BUDGET_BYTES = 64 * 2**20
#: earlier blocks of a step searched for shared columns when a new shape is met
DONORS = 4
#: columns that depend on no shape parameter (bias, temperature, gravity)
_SHAPELESS = frozenset({"bias", "bias_temperature", "g_sensitivity"})


def column_key(name: str, key: Spec, ripple: frozenset[str], vibration: frozenset[str]
               ) -> tuple:
    """What the design column ``name`` depends on, under a step's spec ``key``
    (:func:`~aatest.diagnose.design._step_key`); ``ripple``/``vibration``: the names of those
    table columns in the spec. Any other column (scale, its temperature and cubic terms, a
    plugin effect's columns) depends on the whole sensor chain."""
    if name in _SHAPELESS:
        return (name,)
    timing = (key.delay_s, key.warp_ppm, key.warp_from_start)
    if name == "jerk_sensitivity":
        return (name, timing, key.ripple_motion_deg, key.hysteresis_dps2)
    # the dynamics a step sees: ζ follows the step's amplitude under ``amplitude_damping``
    dynamics = (key.dynamics, key.amplitude_damping)
    if name in ("cross_x", "cross_y"):
        return (name, timing, dynamics)
    if name in ripple:
        return (name, timing, dynamics, key.ripple_cpd)
    if name in vibration:
        return (name, timing, dynamics, key.vibration_hz)
    stiction = key.stiction_dps if name == "rotor_stiction" else 0.0  # only its own column
    return (name, timing, key.ripple_motion_deg, key.hysteresis_dps2, dynamics,
            key.saturation_dps2, key.plugin_shape, stiction)


#: second element of the key of a tone's sine or cosine (a basis column, turned in :func:`gram`)
_BASIS = "tone basis"
#: second element of the key of another step's vibration term (zero on this step)
_OTHER_STEP = "other step"


def _tone_gains(sr: StepReplay, info: ChannelInfo, key: Spec) -> dict[int, complex]:
    """Gain (sensor-axis projection × filters × time shift) of every tone of the step read in
    the frequency domain, by tone index (a ringing filter's tones are left out: built in the
    time domain, under their usual keys)."""
    if not key.vibration_hz or not sr.motor_on:
        return {}
    damped = step_damped(sr, info, key)
    step_s = eval_step_s(sr, damped)
    z_inner = inner_projection(sr, info)
    out = {}
    for j, f_hz in enumerate(damped.vibration_hz):
        gain = tone_gain(sr, info, damped, f_hz, step_s)
        if gain is not None:
            out[j] = z_inner * gain
    return out


def _basis_keys(sr: StepReplay, key: Spec, gains: dict[int, complex]) -> dict[str, tuple]:
    """Column keys of the tones' sines and cosines (they depend on the warp only)."""
    return {f"vib{sr.index}_{j}_{part}": (f"vib{sr.index}_{j}_{part}", _BASIS,
                                           key.vibration_hz[j], key.warp_ppm,
                                           key.warp_from_start, part)
            for j in gains for part in "sc"}


def _rotation(names: list[str], index: int, gains: dict[int, complex]) -> np.ndarray | None:
    """T with (design columns) = T · (stored columns) over ``names``: identity but for each
    tone's sine and cosine, turned by its gain g (s' = Re g·s + Im g·c, c' = Re g·c − Im g·s);
    None when no tone is stored as a basis."""
    where = {n: i for i, n in enumerate(names)}
    pairs = [(where[f"vib{index}_{j}_s"], where[f"vib{index}_{j}_c"], g)
             for j, g in gains.items() if f"vib{index}_{j}_s" in where]
    if not pairs:
        return None
    t = np.eye(len(names))
    for i_s, i_c, g in pairs:
        t[i_s, i_s], t[i_s, i_c], t[i_c, i_s], t[i_c, i_c] = g.real, g.imag, -g.imag, g.real
    return t


def _table_names(spec: Spec, index: int) -> tuple[frozenset[str], frozenset[str]]:
    ripple = frozenset(f"ripple{n:g}_{p}" for n in spec.ripple_cpd for p in "sc")
    vibration = frozenset(f"vib{index}_{j}_{p}" for j in range(len(spec.vibration_hz))
                          for p in "sc")
    return ripple, vibration


class ColumnBudget:
    """Least-recently-used design columns of every step, released beyond the byte budget."""

    def __init__(self, limit_bytes: int) -> None:
        self.limit = limit_bytes
        self.used = 0
        self.order: OrderedDict[tuple, np.ndarray] = OrderedDict()

    def get(self, key: tuple) -> np.ndarray | None:
        col = self.order.get(key)
        if col is not None:
            self.order.move_to_end(key)
        return col

    def put(self, key: tuple, col: np.ndarray) -> None:
        if key in self.order:
            self.order.move_to_end(key)
            return
        self.order[key] = col
        self.used += col.nbytes
        while self.used > self.limit and len(self.order) > 1:
            _, old = self.order.popitem(last=False)
            self.used -= old.nbytes


@dataclass
class StepBlock:
    """One step's design under one shape: its columns' keys and their Gram blocks per fold.

    ``spec`` builds its columns: the shape it was met with, the linear terms of every spec
    that extended it (a plugin effect's columns are built only when it is switched on).
    """

    spec: Spec
    names: list[str]
    keys: list[tuple]
    #: names (with their keys) this step cannot make non-zero under this shape
    zero: dict[str, tuple]
    xtx: np.ndarray  # (2, m, m)
    xty: np.ndarray  # (2, m)
    yty: np.ndarray  # (2,)
    count: np.ndarray  # (2,)
    index: dict[str, int] = field(default_factory=dict)
    #: gain of each tone stored as its sine and cosine (by tone index; see :func:`_rotation`)
    gains: dict[int, complex] = field(default_factory=dict)
    #: column keys of the names asked for, by the tuple of names (computed once per block)
    wanted: dict[tuple[str, ...], dict[str, tuple]] = field(default_factory=dict)


def _columns(sr: StepReplay, info: ChannelInfo, spec: Spec, names: list[str],
             keys: list[tuple], budget: ColumnBudget) -> dict[str, np.ndarray | None]:
    """The columns ``names`` (keys ``keys``) of one step: from the budget, else built (None: a
    column this step holds at zero)."""
    out: dict[str, np.ndarray | None] = {}
    missing = []
    for name, key in zip(names, keys, strict=True):
        col = budget.get((sr.index, key))
        if col is None:
            missing.append(name)
        out[name] = col
    basis = {n: k for n, k in zip(names, keys, strict=True) if n in missing and k[1:2] == (_BASIS,)}
    for name, key in basis.items():
        col = tone_basis_row(sr, key[2], key[3], key[4], key[5])
        budget.put((sr.index, key), col)
        out[name] = col
    rest = [n for n in missing if n not in basis]
    if rest:
        built = _design(sr, info, spec, set(rest))
        for name, key in zip(names, keys, strict=True):
            if name in rest and name in built:
                col = np.ascontiguousarray(built[name], dtype=float)
                budget.put((sr.index, key), col)
                out[name] = col
    return out


def _stack(cols: dict[str, np.ndarray | None], names: list[str]) -> np.ndarray:
    """The named columns as the rows of one (len(names), n) array (each one built: a block's
    columns are never zero)."""
    held = [cols[n] for n in names]
    if any(c is None for c in held):
        raise AssertionError("a block column was not rebuilt")
    return np.stack([c for c in held if c is not None])


def _empty(spec: Spec, sr: StepReplay, y: np.ndarray, gains: dict[int, complex]) -> StepBlock:
    sizes = np.diff(block_edges(sr.n))
    return StepBlock(spec, [], [], {}, np.zeros((2, 0, 0)), np.zeros((2, 0)),
                     fold_products(y, y, sr.n),
                     np.array([sizes[0::2].sum(), sizes[1::2].sum()], dtype=float), gains=gains)


def _adopt(block: StepBlock, donor: StepBlock, wanted: dict[str, tuple]) -> None:
    """Copy into the (empty) ``block`` the Gram entries of the columns ``donor`` shares."""
    shared = [n for n, k in wanted.items() if n in donor.index and donor.keys[donor.index[n]] == k]
    block.zero = {n: k for n, k in wanted.items() if donor.zero.get(n) == k}
    if not shared:
        return
    sub = [donor.index[n] for n in shared]
    block.names, block.keys = list(shared), [wanted[n] for n in shared]
    block.xtx = donor.xtx[:, sub][:, :, sub].copy()
    block.xty = donor.xty[:, sub].copy()
    block.index = {n: j for j, n in enumerate(block.names)}


def _extend(block: StepBlock, sr: StepReplay, info: ChannelInfo, spec: Spec,
            wanted: dict[str, tuple], y: np.ndarray, budget: ColumnBudget) -> None:
    """Build the wanted columns the block lacks and grow its Gram entries by them."""
    missing = [n for n in wanted if n not in block.index and n not in block.zero]
    if not missing:
        return
    block.spec = replace(block.spec, linear=block.spec.linear | spec.linear)
    new = _columns(sr, info, block.spec, missing, [wanted[n] for n in missing], budget)
    added = [n for n in missing if new[n] is not None]
    block.zero |= {n: wanted[n] for n in missing if new[n] is None}
    if not added:
        return
    cols_new = _stack(new, added)
    m, q = len(block.names), len(added)
    xtx = np.zeros((2, m + q, m + q))
    xtx[:, :m, :m] = block.xtx
    if m:
        old = _columns(sr, info, block.spec, block.names, block.keys, budget)
        cross = fold_products(_stack(old, block.names), cols_new, sr.n)
        xtx[:, :m, m:] = cross
        xtx[:, m:, :m] = cross.transpose(0, 2, 1)
    xtx[:, m:, m:] = fold_products(cols_new, cols_new, sr.n)
    block.xtx = xtx
    block.xty = np.concatenate([block.xty, fold_products(cols_new, y, sr.n)], axis=1)
    block.names += added
    block.keys += [wanted[n] for n in added]
    block.index = {n: j for j, n in enumerate(block.names)}


def _wanted(sr: StepReplay, key: Spec, names: list[str], block: StepBlock | None
            ) -> dict[str, tuple]:
    """Column key of every name under the step's spec ``key`` (memoised on the block)."""
    if block is None:
        return {}
    names_key = tuple(names)
    held = block.wanted.get(names_key)
    if held is None:
        ripple, vibration = _table_names(key, sr.index)
        own = f"vib{sr.index}_"
        # another step's vibration terms are zero here whatever the shape (most of the names
        # of a band's model: two per tone per step)
        held = {n: (n, _OTHER_STEP) if n.startswith("vib") and not n.startswith(own)
                else column_key(n, key, ripple, vibration) for n in names}
        held |= {n: k for n, k in _basis_keys(sr, key, block.gains).items() if n in held}
        block.wanted[names_key] = held
    return held


def step_block(sr: StepReplay, info: ChannelInfo, spec: Spec, names: list[str],
               y: np.ndarray, cache: dict[Any, Any]) -> StepBlock:
    """The step's Gram block with (at least) the columns ``names``, from/into ``cache``.

    A shape not met before on this step starts from the most similar of its last
    :data:`DONORS` blocks (most shared column keys).
    """
    key = _step_key(spec, sr)
    budget = cache.setdefault(BUDGET_KEY, ColumnBudget(COLUMN_BUDGET_BYTES))
    bkey = ("step block", sr.index, replace(key, linear=frozenset()))
    block = cache.get(bkey)
    recent: list = cache.setdefault(("recent blocks", sr.index), [])
    wanted = _wanted(sr, key, names, block)
    if block is None:
        block = _empty(spec, sr, y, _tone_gains(sr, info, key))
        wanted = _wanted(sr, key, names, block)
        live = {n: k for n, k in wanted.items() if k[1:2] != (_OTHER_STEP,)}
        donors = [cache[k] for k in recent]
        if donors:
            best = max(donors, key=lambda d: sum(d.keys[d.index[n]] == k for n, k in
                                                 live.items() if n in d.index))
            _adopt(block, best, live)
        block.zero |= {n: k for n, k in wanted.items() if n not in live}
        cache[bkey] = block
    if bkey in recent:
        recent.remove(bkey)
    recent.append(bkey)
    del recent[:-DONORS]
    _extend(block, sr, info, spec, wanted, y, budget)
    return block


def step_design(sr: StepReplay, info: ChannelInfo, spec: Spec, names: list[str],
                y: np.ndarray, cache: dict[Any, Any]) -> tuple[np.ndarray, np.ndarray]:
    """(indices into ``names`` of the columns non-zero on this step, those columns as rows
    (u, n)).

    The columns come from the store of :func:`step_block` (built when released), so a model
    with many step-local columns (vibration tones of every step) is never held as a dense
    (n, p) matrix that is zero in most of its columns.
    """
    block = step_block(sr, info, spec, names, y, cache)
    used = [j for j, n in enumerate(names) if n in block.index]
    budget = cache[BUDGET_KEY]
    cols = _columns(sr, info, block.spec, [names[j] for j in used],
                    [block.keys[block.index[names[j]]] for j in used], budget)
    x = _stack(cols, [names[j] for j in used]) if used else np.zeros((0, sr.n))
    turn = _rotation([names[j] for j in used], sr.index, block.gains)
    if turn is not None:  # the tones' sines and cosines become their design columns
        rows = np.flatnonzero(np.any(turn != np.eye(len(used)), axis=1))
        x[rows] = turn[rows] @ x
    return np.asarray(used, dtype=int), x


__all__ = ["BUDGET_KEY", "COLUMN_BUDGET_BYTES", "ColumnBudget", "StepBlock",
           "column_key", "step_block", "step_design"]


def gram(replay: Replay, info: ChannelInfo, spec: Spec, targets: dict[int, np.ndarray],
         cache: dict | None = None) -> Gram:
    """Per-fold Gram matrices of ``spec`` over all steps, against ``targets[step]`` (volts).

    ``cache`` keeps each step's Gram block under the shape the step depends on, and its design
    columns under what each of them depends on (:mod:`aatest.diagnose.column_store`): a
    search over a shape parameter rebuilds only the columns it can change, and a linear
    extension builds only its new column. Without ``cache`` nothing is kept beyond this call.
    """
    names = column_names(spec, replay)
    p = len(names)
    g = Gram(names, np.zeros((2, p, p)), np.zeros((2, p)), np.zeros(2), np.zeros(2))
    store: dict = cache if cache is not None else {}
    for sr in replay.steps:
        block = step_block(sr, info, spec, names, targets[sr.index], store)
        where = {nm: j for j, nm in enumerate(names)}
        sub = [j for j, nm in enumerate(block.names) if nm in where]
        pos = [where[block.names[j]] for j in sub]
        xtx, xty = block.xtx[:, sub][:, :, sub], block.xty[:, sub]
        turn = _rotation([block.names[j] for j in sub], sr.index, block.gains)
        if turn is not None:  # each tone's sine and cosine turned by its gain
            xtx, xty = turn @ xtx @ turn.T, xty @ turn.T
        ix = np.ix_(pos, pos)
        for f in (0, 1):
            g.xtx[f][ix] += xtx[f]
            g.xty[f][pos] += xty[f]
        g.yty += block.yty
        g.count += block.count
        if cache is None:
            store.clear()
    return g


def fit_spec(replay: Replay, info: ChannelInfo, spec: Spec, targets: dict[int, np.ndarray],
             cache: dict | None = None) -> Fit:
    """Fit ``spec`` to ``targets`` (volts per step); ``cache`` as in :func:`gram`."""
    return fit_gram(gram(replay, info, spec, targets, cache), spec)
