"""What users pass to the PettingZoo adapter, checked: per-agent actions and reset options.

Every mistake raises ``envs.errors.BenchError`` (a ``ValueError``, the exception PettingZoo
and Gymnasium users expect for a bad argument) with one message naming the agent or key
and the offending value. Kept apart from ``envs.warehouse_v0`` so the adapter stays a thin
layer over the core.
"""
from __future__ import annotations

import difflib
import warnings
from collections.abc import Mapping
from typing import Any, cast

import numpy as np

from envs.actions import N_ACTIONS, WAIT
from envs.errors import BenchError

ACTION_NAMES = "0 Up, 1 Down, 2 Left, 3 Right, 4 Wait"
# Python int and every numpy integer scalar type (bool and np.bool_ are not among them).
_INT_TYPES = frozenset({int} | {np.dtype(c).type for c in np.typecodes["AllInteger"]})
_FAST_INT_TYPES = _INT_TYPES - {np.uint64}  # types that always fit int64 (Python ints:
# np.array raises OverflowError beyond int64, caught below)
SCENARIO_KEYS = ("starts", "goals")


def _as_action(value: Any) -> int | None:
    """The action as a Python int, or None if ``value`` is not an integer.

    Integers only: Python ``int`` (not ``bool``), numpy integer scalars and 0-d integer
    arrays (what TorchRL, SuperSuit and ``Discrete.sample()`` hand over). ``1.5``, ``"1"``,
    ``True``, ``None`` and NaN are not actions.
    """
    if type(value) is int:
        return value
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iu":
        return int(value)
    return None


def action_vector(
    actions: Any, names: list[str], agent_ids: Mapping[str, int], live: np.ndarray,
    out: np.ndarray,
) -> np.ndarray:
    """Fill ``out`` ((N,) int64) with the actions of a parallel ``step``.

    ``actions`` maps agent names to actions in 0..4; ``names`` are all N agent names in
    index order and ``agent_ids`` maps each to its index. Every live agent (``live`` (N,) bool)
    needs one. Agents that already left the episode may be absent, map to ``None``, or map
    to any valid action (ignored: a finished robot only Waits); an invalid value is an
    error for them too. Unknown agent names are errors.
    """
    if not isinstance(actions, Mapping):
        raise BenchError(
            f"step: actions must be a dict {{agent: action}}, got {type(actions).__name__}")
    # Fast path (C-level passes): integer types, all in range, names known; the common
    # dict over every agent in index order is converted straight into ``out``.
    keys, values = list(actions), list(actions.values())
    if _FAST_INT_TYPES.issuperset(map(type, values)):
        if keys == names:
            try:
                out[:] = values
            except OverflowError:  # a Python int beyond int64: the slow path names it
                pass
            else:
                if out.view(np.uint64).max() < N_ACTIONS:  # negatives wrap to huge values
                    return out
        else:
            try:
                a = np.array(values, dtype=np.int64)
            except OverflowError:
                a = np.full(1, N_ACTIONS)
            idx = list(map(agent_ids.get, keys))
            if (a.view(np.uint64) < N_ACTIONS).all() and None not in idx:
                rows = cast("list[int]", idx)  # every agent known (no None)
                given = np.zeros(len(out), dtype=bool)
                given[rows] = True
                if (given | ~live).all():
                    out.fill(WAIT)
                    out[rows] = a
                    return out
    # Slow path: the same rules, one agent at a time, to name the first offender.
    out.fill(WAIT)
    given = np.zeros(len(out), dtype=bool)
    for agent, value in actions.items():
        i = agent_ids.get(agent) if isinstance(agent, str) else None
        if i is None:
            raise BenchError(
                f"step: unknown agent {agent!r} (agents are robot_0..robot_{len(out) - 1})")
        if value is None and not live[i]:
            continue
        action = _as_action(value)
        if action is None or not 0 <= action < N_ACTIONS:
            state = "live" if live[i] else "finished"
            raise BenchError(
                f"step: action {value!r} for {state} agent {agent!r} is not an integer in "
                f"0..{N_ACTIONS - 1} ({ACTION_NAMES})")
        out[i] = action
        given[i] = True
    missing = np.flatnonzero(live & ~given)
    if len(missing):
        names = [f"robot_{i}" for i in missing[:5]]
        more = f" and {len(missing) - 5} more" if len(missing) > 5 else ""
        raise BenchError(f"step: no action for live agents {names}{more}")
    return out


def scenario_options(options: Any) -> dict[str, Any]:
    """Check ``reset(options=...)``: None or a dict; returns the scenario keys it holds.

    ``starts``/``goals`` give an explicit scenario (both or neither). A key that looks like
    a misspelling of one of them (``"start"``, ``"Goals"``) is an error; any other key is
    ignored with a warning (PettingZoo's ``parallel_api_test`` passes ``{"options": 1}``).
    """
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise BenchError(
            f"reset: options must be a dict such as {{'starts': [(row, col), ...], 'goals': "
            f"[...]}} or None, got {type(options).__name__} {options!r}")
    chosen = {}
    for key in options:
        if key in SCENARIO_KEYS:
            chosen[key] = options[key]
            continue
        close = difflib.get_close_matches(str(key), SCENARIO_KEYS, n=1, cutoff=0.7)
        if close:
            raise BenchError(f"reset: unknown option {key!r}; did you mean {close[0]!r}?")
        warnings.warn(f"reset: option {key!r} is not used by warehouse_v0 (it knows "
                      f"{', '.join(SCENARIO_KEYS)}); ignored", UserWarning, stacklevel=3)
    if chosen and len(chosen) != len(SCENARIO_KEYS):
        raise BenchError("reset options: give both 'starts' and 'goals' (lists of (row, col))")
    return {key: _integer_cells(key, cells) for key, cells in chosen.items()}


def _integer_cells(what: str, cells: Any) -> np.ndarray:
    """(row, col) pairs as an int64 array; floats (even 1.0), bools and strings rejected
    instead of truncated. Shape and range are checked by ``validate_scenario``."""
    try:
        arr = np.asarray(cells)
    except ValueError as exc:
        raise BenchError(f"reset options: {what} must be a list of (row, col) pairs: {exc}") from None
    items = np.asarray(cells, dtype=object).reshape(-1)
    flags = [isinstance(x, (bool, np.bool_)) for x in items]
    if arr.size and (arr.dtype.kind not in "iu" or any(flags)):
        first = items[flags.index(True) if any(flags) else 0]
        kind = "bool" if any(flags) else str(arr.dtype)
        raise BenchError(
            f"reset options: {what} must hold integer (row, col) pairs, got {kind} values "
            f"such as {first!r}")
    return arr.astype(np.int64)
