"""The vectorized safety filter agrees with a slow, obviously-correct enumerator (Algorithm 1).

The reference below builds every candidate with itertools, orders each deviation level by
the policy's probability (stable, so ties keep the lexicographic order), examines them one
by one against eq:safety_conditions written out literally, and stops at the first
admissible one or at the budget. Random cases: small layouts with shelves, 1..6 robot
slots (padding, finished robots that stay on the floor), neighbour robots anywhere
(predictions may be wrong), radius 0..3, budgets from 1 to unlimited, log-probabilities
with and without exact ties. Runtime: about 3 s.
"""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from algorithms.hierarchical.safety_filter import SafetyFilter, lemma1_count
from envs.actions import N_ACTIONS, WAIT
from envs.layouts import Layout, from_ascii

LAYOUT = from_ascii(
    """
.......
.@@.@@.
.......
.@@.@@.
.......
""",
    name="filter-test",
)


def reference_filter(layout: Layout, pos, occupies, controlled, proposal, logp, nbr_pos,
                     nbr_present, radius: int, c_max: int):
    """One group, literally: returns (actions, examined, fallback, n_candidates_within_L)."""
    nxt, valid = layout.next_cell, layout.move_valid
    n = len(pos)
    omega = {int(nxt[nbr_pos[j], a]) for j in range(len(nbr_pos)) if nbr_present[j] for a in range(N_ACTIONS)}
    ctl = [i for i in range(n) if controlled[i] and occupies[i]]
    occ = [i for i in range(n) if occupies[i]]
    prop = [int(proposal[i]) if i in ctl else WAIT for i in range(n)]

    def admissible(u):
        new = {i: int(nxt[pos[i], u[i]]) for i in occ}
        for i in ctl:
            if not valid[pos[i], u[i]] or new[i] in omega:  # conditions 1 and 4
                return False
        for i, j in itertools.combinations(occ, 2):
            if new[i] == new[j]:  # condition 2
                return False
            if new[i] == pos[j] and new[j] == pos[i]:  # condition 3
                return False
        return True

    if not ctl:
        return np.array(prop), 0, False, 0
    levels = []
    for d in range(radius + 1):
        level = []
        for s in itertools.combinations(ctl, d):
            alts = [[b for b in range(N_ACTIONS) if b != prop[i]] for i in s]
            for acts in itertools.product(*alts):
                u = list(prop)
                score = 0.0
                for i, a in zip(s, acts, strict=True):
                    u[i] = a
                    score += float(logp[i, a]) - float(logp[i, prop[i]])
                level.append((score, u))
        level.sort(key=lambda c: -c[0])  # stable: ties stay lexicographic
        levels.append(level)
    total = sum(len(level) for level in levels)
    examined = 0
    for _, u in itertools.chain.from_iterable(levels):
        if examined == c_max:
            break
        examined += 1
        if admissible(u):
            return np.array(u), examined, False, total
    return np.full(n, WAIT), examined, True, total


def random_case(rng: np.random.Generator, n: int):
    f = LAYOUT.n_free
    cells = rng.choice(f, size=n, replace=False)
    occupies = rng.random(n) < 0.85
    controlled = occupies & (rng.random(n) < 0.85)
    pos = np.where(occupies, cells, -1)
    proposal = rng.integers(0, N_ACTIONS, size=n)
    if rng.random() < 0.3:  # exact ties everywhere (e.g. an untrained, uniform policy)
        logp = np.full((n, N_ACTIONS), -math.log(N_ACTIONS))
    else:
        logp = np.log(rng.dirichlet(np.ones(N_ACTIONS) * 0.7, size=n))
        if rng.random() < 0.3:
            logp[rng.random((n, N_ACTIONS)) < 0.3] = -1e9  # masked moves
    r = int(rng.integers(0, 6))
    nbr_pos = rng.integers(0, f, size=r)
    nbr_present = rng.random(r) < 0.8
    return pos, occupies, controlled, proposal, logp, nbr_pos, nbr_present


@pytest.mark.parametrize("seed", range(6))
def test_safety_filter__vectorized_matches_reference_enumerator(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for radius in range(4):
        for c_max in (1, 3, 12, 60, 10**6):
            cases = [random_case(rng, int(rng.integers(1, 7))) for _ in range(12)]
            n = max(len(c[0]) for c in cases)
            g, r = len(cases), max(len(c[5]) for c in cases)
            pos = np.full((g, n), -1)
            occ = np.zeros((g, n), bool)
            ctl = np.zeros((g, n), bool)
            prop = np.full((g, n), WAIT)
            logp = np.zeros((g, n, N_ACTIONS))
            nbr = np.zeros((g, r), np.int64)
            nbr_on = np.zeros((g, r), bool)
            for k, (p, o, c, u, lp, npos, non) in enumerate(cases):
                m = len(p)
                pos[k, :m], occ[k, :m], ctl[k, :m], prop[k, :m], logp[k, :m] = p, o, c, u, lp
                nbr[k, : len(npos)], nbr_on[k, : len(npos)] = npos, non
            filt = SafetyFilter(LAYOUT, radius, c_max)
            out = filt(pos, occ, ctl, prop, logp, filt.blocked_cells(nbr, nbr_on))
            for k, (p, o, c, u, lp, npos, non) in enumerate(cases):
                m = len(p)
                want, examined, fallback, _ = reference_filter(
                    LAYOUT, np.maximum(p, 0), o, c, u, lp, npos, non, radius, c_max)
                ctx = f"case {k} radius {radius} c_max {c_max}"
                assert out.examined[k] == examined, ctx
                assert bool(out.fallback[k]) == fallback, ctx
                sel = o  # robots on the floor: absent and padding slots are irrelevant
                assert (out.actions[k, :m][sel] == want[sel]).all(), ctx
                assert bool(out.called[k]) == bool((c & o).any()), ctx


@pytest.mark.parametrize("n_z,radius", [(1, 1), (3, 2), (4, 2), (5, 3), (6, 2)])
def test_safety_filter__lemma1_count_and_guarantee(n_z: int, radius: int) -> None:
    """With nothing admissible the filter examines exactly sum_{d<=L} C(n,d)(m-1)^d
    candidates (the enumerator's count); with C_max equal to that count, an admissible
    candidate within radius L is always found when one exists."""
    rng = np.random.default_rng(100 + n_z)
    bound = lemma1_count(n_z, radius)
    filt = SafetyFilter(LAYOUT, radius, bound)
    found_some = 0
    for _ in range(40):
        cells = rng.choice(LAYOUT.n_free, size=n_z, replace=False)
        on = np.ones(n_z, bool)
        prop = rng.integers(0, N_ACTIONS, size=n_z)
        logp = np.log(rng.dirichlet(np.ones(N_ACTIONS), size=n_z))
        nbr = rng.integers(0, LAYOUT.n_free, size=4)
        nbr_on = rng.random(4) < 0.7
        # Everything blocked: nothing is admissible, every candidate is examined.
        all_blocked = np.ones((1, LAYOUT.n_free), bool)
        out = filt(cells[None], on[None], on[None], prop[None], logp[None], all_blocked)
        _, _, _, total = reference_filter(LAYOUT, cells, on, on, prop, logp, [], [], radius, 10**9)
        assert total == bound
        assert out.examined[0] == bound and out.fallback[0]
        # Real neighbours: found iff the reference with an unlimited budget finds one.
        out = filt(cells[None], on[None], on[None], prop[None], logp[None],
                   filt.blocked_cells(nbr[None], nbr_on[None]))
        _, _, fb_unlimited, _ = reference_filter(LAYOUT, cells, on, on, prop, logp, nbr, nbr_on, radius, 10**9)
        assert bool(out.fallback[0]) == fb_unlimited
        found_some += not fb_unlimited
    assert found_some > 0


def test_safety_filter__fallback_is_joint_wait() -> None:
    """Two robots of one group boxed in by a neighbour: nothing admissible -> all Wait."""
    layout = from_ascii("@@@@@\n@...@\n@@@@@")
    pos = np.array([[0, 2]])  # cells (1,1) and (1,3); the neighbour sits on (1,2)
    filt = SafetyFilter(layout, radius=2, c_max=500)
    blocked = filt.blocked_cells(np.array([[1]]), np.array([[True]]))
    on = np.ones((1, 2), bool)
    out = filt(pos, on, on, np.array([[3, 2]]), np.log(np.full((1, 2, 5), 0.2)), blocked)
    assert out.fallback[0]
    assert (out.actions == WAIT).all()
    assert out.examined[0] == lemma1_count(2, 2)


def test_safety_filter__admissible_proposal_is_kept_and_finished_robots_untouched() -> None:
    layout = from_ascii(".....\n.....\n.....")
    filt = SafetyFilter(layout, radius=2, c_max=500)
    pos = np.array([[0, 7, 14]])
    occ = np.array([[True, True, True]])
    ctl = np.array([[True, True, False]])  # slot 2 finished but on the floor ("stay")
    prop = np.array([[3, 1, 0]])
    out = filt(pos, occ, ctl, prop, np.log(np.full((1, 3, 5), 0.2)), np.zeros((1, layout.n_free), bool))
    assert out.examined[0] == 1 and not out.fallback[0]
    assert out.actions[0].tolist() == [3, 1, WAIT]


BIG = from_ascii(
    """
.............
.@@@.@@@.@@@.
.............
.@@@.@@@.@@@.
.............
.@@@.@@@.@@@.
.............
""",
    name="filter-test-big",
)


@pytest.mark.parametrize("seed", range(3))
def test_safety_filter__large_groups_match_reference(seed: int) -> None:
    """Groups of 8..12 robots, mostly waiting proposals with a few violations: deviation-2
    levels with hundreds of candidates, hits deep inside a level, budgets cutting a level."""
    rng = np.random.default_rng(1000 + seed)
    for c_max in (30, 200, 2000):
        cases = []
        for _ in range(8):
            n = int(rng.integers(8, 13))
            cells = rng.choice(BIG.n_free, size=n, replace=False)
            prop = np.where(rng.random(n) < 0.6, WAIT, rng.integers(0, N_ACTIONS, size=n))
            logp = np.log(rng.dirichlet(np.ones(N_ACTIONS), size=n))
            nbr = rng.integers(0, BIG.n_free, size=int(rng.integers(0, 5)))
            cases.append((cells, np.ones(n, bool), rng.random(n) < 0.9, prop, logp, nbr))
        g, n_max, r = len(cases), max(len(c[0]) for c in cases), max(max(len(c[5]) for c in cases), 1)
        pos = np.zeros((g, n_max), np.int64)
        occ, ctl = np.zeros((g, n_max), bool), np.zeros((g, n_max), bool)
        prop, logp = np.full((g, n_max), WAIT), np.zeros((g, n_max, N_ACTIONS))
        nbr, nbr_on = np.zeros((g, r), np.int64), np.zeros((g, r), bool)
        for k, (p, o, c, u, lp, npos) in enumerate(cases):
            m = len(p)
            pos[k, :m], occ[k, :m], ctl[k, :m], prop[k, :m], logp[k, :m] = p, o, c, u, lp
            nbr[k, : len(npos)], nbr_on[k, : len(npos)] = npos, True
        filt = SafetyFilter(BIG, 2, c_max)
        out = filt(pos, occ, ctl, prop, logp, filt.blocked_cells(nbr, nbr_on))
        for k, (p, o, c, u, lp, npos) in enumerate(cases):
            want, examined, fallback, _ = reference_filter(
                BIG, p, o, c, u, lp, npos, np.ones(len(npos), bool), 2, c_max)
            assert out.examined[k] == examined and bool(out.fallback[k]) == fallback
            assert (out.actions[k, : len(p)] == want).all()


OPEN = from_ascii(
    """
......
......
......
......
""",
    name="filter-test-open",
)


def clump_case(rng: np.random.Generator):
    """4..6 robots packed in a 3x3 block of an open floor, proposals that collide with each
    other and neighbours placed next to the block: proposals violate (1)-(4) for several
    robots at once, so deviation-3 candidates are examined and many of them clash among
    the changed robots (same new cell or a swap) or leave conflicting pairs of the
    proposal among them."""
    n = int(rng.integers(4, 7))
    r0, c0 = int(rng.integers(0, 2)), int(rng.integers(0, 4))
    block = [OPEN.cell_index[r0 + dr, c0 + dc] for dr in range(3) for dc in range(3)]
    cells = rng.choice(block, size=n, replace=False)
    prop = rng.integers(0, N_ACTIONS, size=n)
    logp = np.log(rng.dirichlet(np.ones(N_ACTIONS), size=n))
    outside = np.setdiff1d(np.arange(OPEN.n_free), block)
    nbr = rng.choice(outside, size=int(rng.integers(0, 3)), replace=False)
    return cells, prop, logp, nbr


def run_cases(filt: SafetyFilter, cases, layout: Layout = OPEN):
    g, n_max = len(cases), max(len(c[0]) for c in cases)
    r = max(max(len(c[3]) for c in cases), 1)
    pos = np.zeros((g, n_max), np.int64)
    occ = np.zeros((g, n_max), bool)
    prop, logp = np.full((g, n_max), WAIT), np.zeros((g, n_max, N_ACTIONS))
    nbr, nbr_on = np.zeros((g, r), np.int64), np.zeros((g, r), bool)
    for k, (p, u, lp, npos) in enumerate(cases):
        m = len(p)
        pos[k, :m], occ[k, :m], prop[k, :m], logp[k, :m] = p, True, u, lp
        nbr[k, : len(npos)], nbr_on[k, : len(npos)] = npos, True
    return filt(pos, occ, occ, prop, logp, filt.blocked_cells(nbr, nbr_on))


def test_safety_filter__deviation3_with_clashes_matches_reference() -> None:
    """Packed groups at radius 3: the vectorized level-3 search (clash accumulation over
    every pair of changed robots, the swap test, the proposal's conflicting pairs among the
    changed robots) agrees with the enumerator, and level 3 is where many cases resolve."""
    rng = np.random.default_rng(7)
    cases = [clump_case(rng) for _ in range(150)]
    filt = SafetyFilter(OPEN, 3, 10**6)
    out = run_cases(filt, cases)
    at_level3 = 0
    for k, (p, u, lp, npos) in enumerate(cases):
        on = np.ones(len(p), bool)
        want, examined, fallback, _ = reference_filter(OPEN, p, on, on, u, lp, npos, on[: len(npos)], 3, 10**9)
        assert out.examined[k] == examined and bool(out.fallback[k]) == fallback, k
        assert (out.actions[k, : len(p)] == want).all(), k
        at_level3 += int(not fallback and (want != u).sum() == 3)
    assert at_level3 >= 10


def test_safety_filter__deviation3_hand_made_swap_and_same_cell() -> None:
    """Robots A, B, C on (1,1), (1,2), (1,3) under a wall all propose Up (invalid): all
    three must change, so only deviation 3 can succeed. Per robot pi(Right, Wait, Down) =
    (.5, .3, .1) for A and pi(Left, Wait, Right or Down) = (.5, .3, .1) for B and C. By
    score the level-3 candidates run (R,L,L) .125: A-B swap and A, C on (1,2); then at .075
    (W,L,L), (R,W,L), (R,L,W): B onto A's cell, A onto B's, the A-B swap; then at .045
    (W,W,L), (W,L,W), (R,W,W): one robot onto a waiting one's cell; then (W,W,W) .027, the
    winner: 1 + 60 (levels 1-2) + 8 candidates examined."""
    layout = from_ascii("@@@@@@\n......\n......", name="hand3")
    ci = layout.cell_index
    pos = np.array([[ci[1, 1], ci[1, 2], ci[1, 3]]])
    prop = np.array([[0, 0, 0]])  # Up into the wall: condition (1) fails for all three
    probs = np.array([[0.05, 0.1, 0.05, 0.5, 0.3],  # A: Up, Down, Left, Right, Wait
                      [0.05, 0.05, 0.5, 0.1, 0.3],  # B
                      [0.05, 0.1, 0.5, 0.05, 0.3]])  # C
    logp = np.log(probs)[None]
    on = np.ones((1, 3), bool)
    filt = SafetyFilter(layout, 3, 10**6)
    out = filt(pos, on, on, prop, logp, np.zeros((1, layout.n_free), bool))
    assert out.actions[0].tolist() == [WAIT, WAIT, WAIT] and not out.fallback[0]
    assert out.examined[0] == 1 + 3 * 4 + 3 * 16 + 8
    want, examined, fallback, _ = reference_filter(layout, pos[0], on[0], on[0], prop[0], logp[0], [], [], 3, 10**9)
    assert (want == out.actions[0]).all() and examined == out.examined[0] and not fallback


def test_safety_filter__too_many_candidates_guard(monkeypatch: pytest.MonkeyPatch) -> None:
    """Level 3 over m = 4 robots enumerates C(4,3) 4^3 = 256 candidates per group: a limit
    of exactly 256 runs, 255 is a BenchError naming the count, deviation and group size."""
    import algorithms.hierarchical.safety_filter as sf
    from envs.errors import BenchError

    rng = np.random.default_rng(3)
    while True:  # a 4-robot clump whose search reaches deviation 3
        case = clump_case(rng)
        if len(case[0]) == 4 and run_cases(SafetyFilter(OPEN, 2, 10**6), [case]).fallback[0] \
                and not run_cases(SafetyFilter(OPEN, 3, 10**6), [case]).fallback[0]:
            break
    filt = SafetyFilter(OPEN, 3, 10**6)
    monkeypatch.setattr(sf, "MAX_LEVEL_CANDIDATES", 256)
    assert not run_cases(filt, [case]).fallback[0]
    monkeypatch.setattr(sf, "MAX_LEVEL_CANDIDATES", 255)
    with pytest.raises(BenchError, match=r"256 candidates at deviation 3 for 4 robots"):
        run_cases(filt, [case])
