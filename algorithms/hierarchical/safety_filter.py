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
  docs/decisions/0110), (4) ends outside every neighbour's reachable set, and no two robots
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
from typing import cast

import numpy as np

from envs.actions import N_ACTIONS, WAIT
from envs.errors import BenchError
from envs.layouts import Layout

# ALTERNATIVES[a] = the four controls other than a, ascending.
ALTERNATIVES = np.array([[b for b in range(N_ACTIONS) if b != a] for a in range(N_ACTIONS)])
MAX_LEVEL_CANDIDATES = 20_000_000


def lemma1_count(n_z: int, radius: int, m: int = N_ACTIONS) -> int:
    """Number of joint controls within deviation ``radius`` of a proposal (Lemma 1): the
    budget the filter needs to examine them all, and the bound the Lemma 1 claim checks."""
    # eq:lemma:safety_bound: sum_{d=0}^{L} C(n_z, d) (m - 1)^d, m = |U|
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
        p = np.take_along_axis(np.maximum(pos, 0), perm, axis=1)
        occ = np.take_along_axis(occupies, perm, axis=1)
        ctl = np.take_along_axis(controlled, perm, axis=1)
        prop = np.where(ctl, np.take_along_axis(proposal, perm, axis=1), WAIT)
        gi = np.arange(g_all)

        # Level 0 for every group: the proposal's violations (eq:safety_conditions).
        nxt = self.next[p]  # (G, n, 5)
        unary = (self.valid[p] & ~blocked[gi[:, None, None], nxt]) | ~ctl[..., None]  # (1), (4)
        nprop = np.take_along_axis(nxt, prop[..., None], axis=2)[..., 0]  # (G, n)
        pair = occ[:, :, None] & occ[:, None, :] & ~np.eye(n, dtype=bool)
        p0 = ((nprop[:, :, None] == nprop[:, None, :])  # (2)
              | ((nprop[:, :, None] == p[:, None, :]) & (nprop[:, None, :] == p[:, :, None]))) & pair  # (3)
        bad = ~np.take_along_axis(unary, prop[..., None], axis=2)[..., 0]
        called = cast(np.ndarray, ctl.any(axis=1))  # (G,) bool: with an axis, an array
        found = called & ~bad.any(axis=1) & ~p0.any(axis=(1, 2))
        actions = prop.copy()
        examined = called.astype(np.int64)
        fallback = called & ~found

        todo = np.flatnonzero(fallback) if self.radius > 0 and self.c_max > 1 else np.zeros(0, np.int64)
        if todo.size:
            level_actions, level_examined, level_found = self._search(
                p[todo], occ[todo], ctl[todo], prop[todo], nxt[todo], unary[todo], p0[todo],
                bad[todo], pair[todo], np.take_along_axis(logp[todo], perm[todo, :, None], axis=1))
            actions[todo] = level_actions
            examined[todo] += level_examined
            fallback[todo] = ~level_found
        actions[fallback] = WAIT
        out = np.empty_like(actions)
        np.put_along_axis(out, perm, actions, axis=1)
        return FilterResult(out, examined, fallback, called)

    def _search(self, p: np.ndarray, occ: np.ndarray, ctl: np.ndarray, prop: np.ndarray, nxt: np.ndarray,
                unary: np.ndarray, p0: np.ndarray, bad: np.ndarray, pair: np.ndarray, logp: np.ndarray,
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Deviation levels 1..L for U groups whose proposal is inadmissible.

        Everything is indexed by alternative (robot slot i, k-th control other than U~_i):
        new cell, unary admissibility, conflicts with every other robot's proposed control
        (U, n, 4, n). Returns (actions (U, n), examined after the proposal (U,), found (U,)).
        """
        u_n = p.shape[0]
        alt_act = ALTERNATIVES[prop]  # (U, n, 4)
        new = np.take_along_axis(nxt, alt_act, axis=2)  # (U, n, 4)
        u_alt = np.take_along_axis(unary, alt_act, axis=2)
        nprop = np.take_along_axis(nxt, prop[..., None], axis=2)[..., 0]
        conf = ((new[..., None] == nprop[:, None, None, :])
                | ((new[..., None] == p[:, None, None, :]) & (nprop[:, None, None, :] == p[:, :, None, None])))
        conf &= pair[:, :, None, :]  # (U, n, 4, n): (i, alt k) vs (j, U~_j)
        c1 = conf.sum(-1)  # (U, n, 4)
        deg = p0.sum(-1)  # (U, n)
        bad_total, pairs_total = bad.sum(-1), deg.sum(-1) // 2
        lp_prop = np.take_along_axis(logp, prop[..., None], axis=2)
        delta = np.take_along_axis(logp, alt_act, axis=2) - lp_prop  # (U, n, 4) score terms
        n_ctl = ctl.sum(-1)

        actions = prop.copy()
        examined = np.zeros(u_n, dtype=np.int64)
        found = np.zeros(u_n, dtype=bool)
        budget = np.full(u_n, self.c_max - 1, dtype=np.int64)
        for d in range(1, self.radius + 1):
            todo = np.flatnonzero(~found & (budget > 0) & (n_ctl >= d))
            if todo.size == 0:
                break
            m = int(n_ctl[todo].max())
            n_level = np.array([math.comb(c, d) for c in range(m + 1)])[n_ctl[todo]] * 4**d
            # Robots violating (1) or (4) under the proposal must all change: with more than
            # d of them nothing at this level is admissible, only the count matters.
            sel = todo[bad_total[todo] <= d]
            hit_all = np.zeros(todo.size, dtype=bool)
            rank_all = np.zeros(todo.size, dtype=np.int64)
            if sel.size:
                m = int(n_ctl[sel].max())
                if d == 1:
                    k = m * 4
                    exists = np.broadcast_to(ctl[sel, :m, None], (sel.size, m, 4)).reshape(sel.size, k)
                    ok = (u_alt[sel, :m] & (c1[sel, :m] == 0)
                          & ((bad_total[sel, None] - bad[sel, :m]) == 0)[..., None]
                          & ((pairs_total[sel, None] - deg[sel, :m]) == 0)[..., None]).reshape(sel.size, k)
                    ok &= exists
                    score = delta[sel, :m].reshape(sel.size, k)
                    rob, alt = _level_tables_dense1(m)
                elif d == 2:
                    ok, score, exists, rob, alt = self._level2(
                        sel, m, ctl, p, new, u_alt, conf, c1, bad, bad_total, deg, pairs_total, p0, delta)
                    k = score.shape[1]
                else:
                    ok, score, exists, rob, alt = self._level_general(
                        sel, m, d, ctl, p, new, u_alt, conf, c1, bad, bad_total, deg, pairs_total, p0, delta)
                    k = score.shape[1]
                # The best admissible candidate and its rank in the level's order.
                best = np.where(ok, score, -np.inf).max(-1)
                kstar = np.argmax(ok & (score == best[:, None]), axis=-1)
                ahead = (score > best[:, None]) | ((score == best[:, None]) & (np.arange(k) < kstar[:, None]))
                rank = (exists & ahead).sum(-1)
                hit = ok.any(-1) & (rank < budget[sel])
                at = np.searchsorted(todo, sel)
                hit_all[at], rank_all[at] = hit, rank
                hs = sel[hit]
                if hs.size:
                    kh = kstar[hit]
                    actions[hs[:, None], rob[kh]] = alt_act[hs[:, None], rob[kh], alt[kh]]
                    found[hs] = True
            examined[todo] += np.where(hit_all, rank_all + 1, np.minimum(n_level, budget[todo]))
            budget[todo] = np.where(hit_all, 0, np.maximum(budget[todo] - n_level, 0))
        return actions, examined, found

    @staticmethod
    def _level2(sel, m, ctl, p, new, u_alt, conf, c1, bad, bad_total, deg, pairs_total, p0, delta):
        """Deviation 2 over the robot pairs i < j (lexicographic) and their controls (a, b):
        (U', K) ok, score, exists with K = C(m, 2) x 16, in the level's order."""
        s = sel.size
        rob, alt = _level_tables(m, 2)  # (i < j, a, b) in the level's order, 16 rows per pair
        iu, ju = rob[::16, 0], rob[::16, 1]  # (P,) each
        nw, ua, c = new[sel, :m], u_alt[sel, :m], c1[sel, :m]
        ps, cs, ds, bs, dl = p[sel], ctl[sel], deg[sel], bad[sel], delta[sel]  # gathered once
        # Robot pair (i, j): the rest of the proposal is clean once i and j change.
        base = ((bad_total[sel, None] - bs[:, iu] - bs[:, ju]) == 0) & (
            (pairs_total[sel, None] - ds[:, iu] - ds[:, ju] + p0[sel][:, iu, ju]) == 0)  # (U', P)
        # (i, a) is clean against every unchanged robot but j: clean[u, i, j, a].
        clean = ((c[..., None] - conf[sel, :m, :, :m]) == 0).transpose(0, 1, 3, 2)
        clean_i = clean[:, iu, ju][..., :, None]  # (U', P, a, 1)
        clean_j = clean[:, ju, iu][..., None, :]  # (U', P, 1, b)
        ni, nj = nw[:, iu][..., :, None], nw[:, ju][..., None, :]
        clash = (ni == nj) | ((ni == ps[:, ju, None, None]) & (nj == ps[:, iu, None, None]))
        ok = (base[..., None, None] & clean_i & clean_j & ~clash
              & ua[:, iu][..., :, None] & ua[:, ju][..., None, :])
        exists = np.broadcast_to((cs[:, iu] & cs[:, ju])[..., None, None], ok.shape)
        score = dl[:, iu][..., :, None] + dl[:, ju][..., None, :]
        k = rob.shape[0]
        return (ok & exists).reshape(s, k), score.reshape(s, k), exists.reshape(s, k), rob, alt

    @staticmethod
    def _level_general(sel, m, d, ctl, p, new, u_alt, conf, c1, bad, bad_total, deg, pairs_total, p0, delta):
        """Deviation d >= 3 by explicit enumeration of (slots, alternatives) tuples."""
        rob, alt = _level_tables(m, d)
        k = rob.shape[0]
        if k * sel.size > MAX_LEVEL_CANDIDATES:
            raise BenchError(
                f"safety filter: {k} candidates at deviation {d} for {m} robots; lower search_radius or c_max")
        gg = sel[:, None, None]
        r, a = rob[None], alt[None]
        exists = ctl[gg, r].all(-1)  # (U', K)
        score = delta[gg, r, a].sum(-1)
        ok = exists & u_alt[gg, r, a].all(-1)
        ok &= bad_total[sel, None] - bad[gg, r].sum(-1) == 0
        rest_pairs = pairs_total[sel, None] - deg[gg, r].sum(-1)
        nw = new[gg, r, a]  # (U', K, d)
        clash = np.zeros(ok.shape, dtype=bool)
        for e in range(d):
            for f in range(e + 1, d):
                rest_pairs = rest_pairs + p0[sel[:, None], rob[None, :, e], rob[None, :, f]]
                clash |= (nw[..., e] == nw[..., f]) | (
                    (nw[..., e] == p[sel[:, None], rob[None, :, f]]) & (nw[..., f] == p[sel[:, None], rob[None, :, e]]))
        ok &= (rest_pairs == 0) & ~clash
        vs_changed = conf[gg[..., None], r[..., None], a[..., None], rob[None, :, None, :]].sum(-1)
        ok &= (c1[gg, r, a] - vs_changed == 0).all(-1)
        return ok, score, exists, rob, alt


@lru_cache(maxsize=64)
def _level_tables_dense1(m: int) -> tuple[np.ndarray, np.ndarray]:
    """(4m, 1) slots and alternatives of deviation-1 candidates, (i, a) order."""
    return np.repeat(np.arange(m), 4)[:, None], np.tile(np.arange(4), m)[:, None]

