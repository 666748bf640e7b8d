"""The predictive safety filter (Algorithm 1), vectorized over groups and candidates.

For each (episode, group) pair g of a step, with the group's robot slots padded to n:

* eq:interaction_prediction: the reachable sets Omega_{t+1}^{j,z'} of every neighbour
  robot j (received or predicted position, all five controls) are unioned into a boolean
  map ``blocked`` (G, F) over the free cells.
* eq:safety_deviation: candidates U differ from the proposal U~ in D = #changed robots;
  they are examined in nondecreasing D, within radius L and budget C_max (the proposal
  itself, D = 0, is the first candidate examined). Within one deviation level candidates
  are ordered by the local policy's probability, descending: the score of U is
  log pi(U | w) - log pi(U~ | w) = sum over changed robots of the per-robot log-prob
  differences (the policy is a product of per-robot categoricals); exact ties keep the
  lexicographic order (changed robot slots ascending, then their controls ascending).
* eq:safety_prediction / eq:safety_conditions: U is admissible iff every controlled robot
  (1) makes a valid move (a move into a shelf or off the grid counts as leaving P, see
  docs/decisions.md), (4) ends outside every neighbour's reachable set, and no two robots
  of the group (2) end on the same cell or (3) swap cells.
* First admissible wins; if none is found the group executes joint Wait (the fallback).

Robots that are not controlled (finished, or padding) are never modified: a finished
robot still on the floor (``on_goal="stay"``) Waits and counts as an obstacle for (2)-(3).

Vectorization: per-robot tables (unary admissibility (G, n, 5), conflicts of (robot i,
control a) with every other robot's proposed control (G, n, 5, n)) are computed once;
a candidate with changed set S is then admissible iff counts of violations among the
unchanged robots, minus those involving S, are zero and S's own entries are clean. All
candidates of one level are scored and checked at once for all unresolved groups; the
examined count follows from the rank of the best admissible candidate, without sorting.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from envs.actions import N_ACTIONS, WAIT
from envs.errors import BenchError
from envs.layouts import Layout

# ALTERNATIVES[a] = the four controls other than a, ascending.
ALTERNATIVES = np.array([[b for b in range(N_ACTIONS) if b != a] for a in range(N_ACTIONS)])
MAX_LEVEL_CANDIDATES = 20_000_000


def lemma1_count(n_z: int, radius: int, m: int = N_ACTIONS) -> int:
    """Number of joint controls within deviation ``radius`` of a proposal (Lemma 1)."""
    return sum(math.comb(n_z, d) * (m - 1) ** d for d in range(min(radius, n_z) + 1))


@lru_cache(maxsize=64)
def _level_tables(m: int, d: int) -> tuple[np.ndarray, np.ndarray]:
    """(K, d) robot slots and (K, d) alternative indices of every deviation-d candidate
    over the first m slots, in lexicographic order (slots, then alternatives)."""
    robots = np.array(list(itertools.combinations(range(m), d)), dtype=np.int64).reshape(-1, d)
    alts = np.array(list(itertools.product(range(N_ACTIONS - 1), repeat=d)), dtype=np.int64).reshape(-1, d)
    rob = np.repeat(robots, len(alts), axis=0)
    alt = np.tile(alts, (len(robots), 1))
    return rob, alt


@dataclass
class FilterResult:
    """Outcome for G group-steps."""

    actions: np.ndarray  # (G, n) executed controls U_t^z
    examined: np.ndarray  # (G,) candidates examined (0 where the filter was not called)
    fallback: np.ndarray  # (G,) bool, joint Wait because nothing admissible was found
    called: np.ndarray  # (G,) bool, the group had at least one controlled robot


class SafetyFilter:
    """Algorithm 1 on a fixed layout with search radius L and candidate budget C_max."""

    def __init__(self, layout: Layout, radius: int = 2, c_max: int = 500) -> None:
        if radius < 0 or c_max < 1:
            raise BenchError(f"safety filter: need search_radius >= 0 and c_max >= 1, got {radius}, {c_max}")
        self.next = np.ascontiguousarray(layout.next_cell)  # (F, 5)
        self.valid = np.ascontiguousarray(layout.move_valid)  # (F, 5)
        self.n_free = layout.n_free
        self.radius, self.c_max = int(radius), int(c_max)

    def blocked_cells(self, nbr_pos: np.ndarray, nbr_present: np.ndarray) -> np.ndarray:
        """eq:interaction_prediction: (G, R) neighbour cells, (G, R) present -> (G, F) bool
        union of their one-step reachable sets."""
        g, f = nbr_pos.shape[0], self.n_free
        out = np.zeros(g * (f + 1), dtype=bool)
        reach = self.next[np.maximum(nbr_pos, 0)]  # (G, R, 5)
        flat = np.where(nbr_present[..., None], reach, f) + (np.arange(g) * (f + 1))[:, None, None]
        out[flat.reshape(-1)] = True
        return out.reshape(g, f + 1)[:, :f]

    def __call__(self, pos: np.ndarray, occupies: np.ndarray, controlled: np.ndarray,
                 proposal: np.ndarray, logp: np.ndarray, blocked: np.ndarray) -> FilterResult:
        """Filter G proposals.

        pos (G, n) cell indices (any value on padding), occupies (G, n) bool robots on the
        floor, controlled (G, n) bool robots the group steers (subset of occupies),
        proposal (G, n) controls U~, logp (G, n, 5) float64 per-robot log pi, blocked
        (G, F) bool from ``blocked_cells``.
        """
        g_all, n = pos.shape
        controlled = controlled & occupies
        # Controlled slots first (stable), so level-d candidates enumerate only m columns.
        perm = np.argsort(~controlled, axis=1, kind="stable")
        take = lambda a: np.take_along_axis(a, perm, axis=1)  # noqa: E731
        p, occ, ctl = take(np.maximum(pos, 0)), take(occupies), take(controlled)
        prop = np.where(ctl, take(proposal), WAIT)
        lp = np.take_along_axis(logp, perm[..., None], axis=1).astype(np.float64)
        gi = np.arange(g_all)

        nxt = self.next[p]  # (G, n, 5)
        unary = (self.valid[p] & ~blocked[gi[:, None, None], nxt]) | ~ctl[..., None]
        nprop = np.take_along_axis(nxt, prop[..., None], axis=2)[..., 0]  # (G, n)
        pair = occ[:, :, None] & occ[:, None, :] & ~np.eye(n, dtype=bool)  # (G, n, n)
        conf = (nxt[..., None] == nprop[:, None, None, :]) | (
            (nxt[..., None] == p[:, None, None, :]) & (nprop[:, None, None, :] == p[:, :, None, None])
        )
        conf &= pair[:, :, None, :]  # (G, n, 5, n): (i, a) vs (j, U~_j)
        p0 = np.take_along_axis(conf, prop[:, :, None, None], axis=2)[:, :, 0, :]  # (G, n, n)
        deg = p0.sum(-1)
        pairs_total = deg.sum(-1) // 2
        bad = ~np.take_along_axis(unary, prop[..., None], axis=2)[..., 0]
        bad_total = bad.sum(-1)
        conf_sum = conf.sum(-1)  # (G, n, 5)
        alt_act = ALTERNATIVES[prop]  # (G, n, 4)
        lp_prop = np.take_along_axis(lp, prop[..., None], axis=2)[..., 0]

        called = ctl.any(axis=1)
        actions = prop.copy()
        found = called & (bad_total == 0) & (pairs_total == 0)  # level 0: the proposal
        examined = called.astype(np.int64)
        budget = np.where(called, self.c_max - 1, 0)
        n_ctl = ctl.sum(axis=1)
        for d in range(1, self.radius + 1):
            todo = np.flatnonzero(~found & (budget > 0) & (n_ctl >= d))
            if todo.size == 0:
                break
            m = int(n_ctl[todo].max())
            rob, alt = _level_tables(m, d)
            k = rob.shape[0]
            if k > MAX_LEVEL_CANDIDATES:
                raise BenchError(
                    f"safety filter: {k} candidates at deviation {d} for {m} robots; "
                    "lower search_radius or c_max"
                )
            chunk = max(1, 4_000_000 // max(1, k * d * d))
            for s in range(0, todo.size, chunk):
                sel = todo[s : s + chunk]
                gg = sel[:, None, None]
                act = alt_act[gg, rob[None], alt[None]]  # (Gu, K, d)
                exists = ctl[gg, rob[None]].all(-1)  # (Gu, K)
                score = (lp[gg, rob[None], act] - lp_prop[gg, rob[None]]).sum(-1)
                ok = exists & unary[gg, rob[None], act].all(-1)
                ok &= bad_total[sel, None] - bad[gg, rob[None]].sum(-1) == 0
                rest_pairs = pairs_total[sel, None] - deg[gg, rob[None]].sum(-1)
                clash = np.zeros(ok.shape, dtype=bool)
                new = nxt[gg, rob[None], act]  # (Gu, K, d)
                for e in range(d):
                    for f in range(e + 1, d):
                        rest_pairs = rest_pairs + p0[sel[:, None], rob[None, :, e], rob[None, :, f]]
                        clash |= (new[..., e] == new[..., f]) | (
                            (new[..., e] == p[sel[:, None], rob[None, :, f]])
                            & (new[..., f] == p[sel[:, None], rob[None, :, e]])
                        )
                ok &= (rest_pairs == 0) & ~clash
                vs_changed = conf[gg[..., None], rob[None, :, :, None], act[..., None], rob[None, :, None, :]]
                ok &= (conf_sum[gg, rob[None], act] - vs_changed.sum(-1) == 0).all(-1)
                # The best admissible candidate and its rank in the level's order.
                best = np.where(ok, score, -np.inf).max(-1)
                kstar = np.argmax(ok & (score == best[:, None]), axis=-1)
                ahead = (score > best[:, None]) | ((score == best[:, None]) & (np.arange(k) < kstar[:, None]))
                rank = (exists & ahead).sum(-1)
                hit = ok.any(-1) & (rank < budget[sel])
                n_level = exists.sum(-1)
                examined[sel] += np.where(hit, rank + 1, np.minimum(n_level, budget[sel]))
                budget[sel] = np.where(hit, 0, np.maximum(budget[sel] - n_level, 0))
                hs = sel[hit]
                if hs.size:
                    actions[hs[:, None], rob[kstar[hit]]] = act[np.flatnonzero(hit), kstar[hit]]
                    found[hs] = True
        fallback = called & ~found
        actions[fallback] = WAIT
        out = np.empty_like(actions)
        np.put_along_axis(out, perm, actions, axis=1)
        return FilterResult(out, examined, fallback, called)
