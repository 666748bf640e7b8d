"""Every claim of the paper in one list: the claims of ``paper.claims.claims`` and Table I's
further statements (``paper.claims.table1_claims``, which builds on the former), so neither
module imports the other's importer.

May import: paper.claims.claims, paper.claims.table1_claims.
"""
from __future__ import annotations

import pandas as pd

from paper.claims import claims as C
from paper.claims import table1_claims as T

__all__ = ["all_claims"]


def all_claims(train: pd.DataFrame, evals: pd.DataFrame, at: str = "paper",
               cells: pd.DataFrame | None = None) -> list[C.Claim]:
    """Every claim at the paper's configurations; with ``at="run"`` also at the run's own
    (N, p) (and, for Lemma 1, the run's (N, Z, L, C_max) from ``cells``)."""
    if at not in ("paper", "run"):
        raise ValueError(f"claims at {at!r}: expected 'paper' or 'run'")
    r = at == "run"
    fig1 = C.run_configs(train, ("hierarchical", "decentralized")) if r else []
    gaps = [(big, n, p) for (big, pb) in fig1 for (n, p) in fig1 if pb == p and n < big]
    hier_t = C.run_configs(train, ("hierarchical",)) if r else []
    fig2 = C.run_configs(evals, ("hierarchical", "ic3net")) if r else []
    hier_e = C.run_configs(evals, ("hierarchical",)) if r else []
    lemma: list[tuple] = []
    if r and cells is not None and len(cells):
        h = cells[(cells["method"] == "hierarchical") & cells["safety_filter"].astype(bool)]
        lemma = sorted({(int(a), int(b), int(c), int(d)) for a, b, c, d in
                        h[["n_robots", "groups", "search_radius", "c_max"]].itertuples(index=False)})
    return [C.claim_hier_above_dec(train, run=fig1), C.claim_gap_widens(train, run=gaps),
            C.claim_convergence(train, run=hier_t), C.claim_above_ic3net(evals, run=fig2),
            C.claim_no_collisions(evals, run=hier_e), T.claim_collisions_printed(evals, run=hier_e),
            C.claim_few_corrections(evals, run=hier_e), T.claim_mean_candidates(evals, run=hier_e),
            T.claim_searches_grow(evals), T.claim_normal_search(evals, run=hier_e),
            C.claim_payload_ratio(evals), C.claim_lemma1(run=lemma)]
