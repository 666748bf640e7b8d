"""The ``infos`` of one PettingZoo step, built lazily from the batched core's arrays.

Most training loops never read infos, yet building N dicts of 14 Python scalars costs more
than the core step at N = 100. ``StepInfos`` is a real ``dict`` {agent: info} (PettingZoo's
checkers require ``isinstance(info, dict)``) whose per-agent dicts are made on first access
from (N, ...) column arrays captured at that step. Every read path (``[]``, ``get``,
``items``, ``values``, iteration into ``dict(...)``/``{**...}``, ``copy``, pickling,
``copy.copy``/``deepcopy``, ``==``, ``repr``) returns the built dicts, which are plain,
mutable ``dict``s: SuperSuit and Stable-Baselines3 write keys such as
``"terminal_observation"`` into them.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from _collections_abc import dict_items, dict_values  # the views dict's methods return

INFO_KEYS = (
    "position", "goal", "group", "collision", "at_goal", "invalid", "progress",
    "goal_bonus", "collision_penalty", "time_penalty", "link_available", "message_age",
    "payload_hier", "payload_dec", "t",
)


_ROWS = ("link_available", "message_age")  # (N, Z) columns handed out as row views


class _Pending:
    """The placeholder value of an agent whose info is not built yet (one instance,
    kept by pickle and copy: the adapter stores a ``StepInfos.template``)."""

    __slots__ = ()

    def __reduce__(self) -> str:
        return "_PENDING"

    def __repr__(self) -> str:
        return "<pending info>"


_PENDING = _Pending()


class StepInfos(dict[str, Any]):
    """{agent: info} for one step; see the module docstring.

    ``names`` are the agents (a list, or a ``template(names)`` dict reused across
    steps); ``agent_ids`` maps agent names to robot indices i; ``columns`` (or a function called
    on the first read that returns them, so nothing is computed for unread infos) holds,
    per robot i,
    ``position``/``goal`` (N, 2) (row, col), ``group`` (N,), ``collision``, ``at_goal``,
    ``invalid`` (N,) bool, the four reward terms (N,) float, ``link_available`` (N, Z)
    bool (row i: A_t[:, z_i]), ``message_age`` (N, Z) int (row i: steps since the freshest
    message group z_i holds from each group was sent; 0 for its own); ``constants`` are
    ``payload_hier``, ``payload_dec``, ``t``.
    The arrays must not be modified afterwards (the adapter passes fresh ones).
    """

    __slots__ = ("_ids", "_cols", "_lists", "_const")

    def __init__(self, names: list[str] | dict[str, Any], agent_ids: Mapping[str, int],
                 columns: dict[str, np.ndarray] | Callable[[], dict[str, np.ndarray]],
                 constants: dict[str, int]) -> None:
        dict.update(self, self.template(names) if isinstance(names, list) else names)
        self._ids, self._cols, self._const = agent_ids, columns, constants
        self._lists: dict[str, list[Any]] | None = None

    @staticmethod
    def template(names: list[str]) -> dict[str, Any]:
        """The not-yet-built entries of ``names``: a dict to pass as ``names`` (and reuse
        across steps with the same agents; it is copied, never changed)."""
        return dict.fromkeys(names, _PENDING)

    def _build(self, agent: str) -> dict[str, Any]:
        lists = self._lists
        cols = self._cols
        if callable(cols):
            cols = self._cols = cols()
        if lists is None:  # one tolist per column, the first time any info is read
            lists = self._lists = {k: v.tolist() for k, v in cols.items() if k not in _ROWS}
        i = self._ids[agent]
        info = {
            "position": tuple(lists["position"][i]), "goal": tuple(lists["goal"][i]),
            "group": lists["group"][i], "collision": lists["collision"][i],
            "at_goal": lists["at_goal"][i], "invalid": lists["invalid"][i],
            "progress": lists["progress"][i], "goal_bonus": lists["goal_bonus"][i],
            "collision_penalty": lists["collision_penalty"][i],
            "time_penalty": lists["time_penalty"][i],
            "link_available": cols["link_available"][i],
            "message_age": cols["message_age"][i],
        }
        info.update(self._const)
        return info

    def __getitem__(self, agent: str) -> dict[str, Any]:
        value = dict.__getitem__(self, agent)
        if value is _PENDING:
            value = self._build(agent)
            dict.__setitem__(self, agent, value)
        return value

    def _all(self) -> dict[str, Any]:
        """A plain dict with every info built."""
        return {agent: self[agent] for agent in dict.keys(self)}

    # Every other read path goes through __getitem__ or _all.
    def __iter__(self) -> Iterator[str]:  # also makes dict(x) and {**x} use __getitem__
        return iter(dict.keys(self))

    def get(self, agent: str, default: Any = None) -> Any:
        return self[agent] if dict.__contains__(self, agent) else default

    def items(self) -> dict_items[str, Any]:
        return self._all().items()

    def values(self) -> dict_values[str, Any]:
        return self._all().values()

    def pop(self, agent: str, *default: Any) -> Any:
        if dict.__contains__(self, agent):
            value = self[agent]
            dict.__delitem__(self, agent)
            return value
        return dict.pop(self, agent, *default)

    def popitem(self) -> tuple[str, Any]:
        agent = next(reversed(dict.keys(self)))
        return agent, self.pop(agent)

    def setdefault(self, agent: str, default: Any = None) -> Any:
        return self[agent] if dict.__contains__(self, agent) else dict.setdefault(
            self, agent, default)

    def copy(self) -> dict[str, Any]:
        return self._all()

    __copy__ = copy

    def __reduce__(self) -> tuple[type[dict[str, Any]], tuple[dict[str, Any]]]:
        return (dict, (self._all(),))

    def __eq__(self, other: object) -> bool:
        return self._all() == (other._all() if isinstance(other, StepInfos) else other)

    def __ne__(self, other: object) -> bool:
        return not self == other

    __hash__ = None

    # ignore: dict's overloads return its own key/value types; a built dict here, for any operand
    def __or__(self, other: Any) -> dict[str, Any]:  # type: ignore[override]
        return self._all() | other

    # ignore: as __or__
    def __ror__(self, other: Any) -> dict[str, Any]:  # type: ignore[override]
        return other | self._all()

    def __repr__(self) -> str:
        return repr(self._all())
