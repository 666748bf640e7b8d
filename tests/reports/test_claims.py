"""Each claim's verdict on synthetic tables built to hold, built to fail, and with
configurations missing (reports/claims.py). Runtime: about 3 s."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from reports.claims import (
    FAILS,
    HOLDS,
    NO_DATA,
    all_claims,
    claim_above_ic3net,
    claim_convergence,
    claim_gap_widens,
    claim_hier_above_dec,
    claim_payload_ratio,
    claim_safety,
    claims_markdown,
    combine,
)
from tests.reports.synthetic import frames, joined

KEYS = ["hier_above_dec", "gap_widens", "convergence", "above_ic3net", "payload_ratio", "safety"]


@pytest.fixture(scope="module")
def holding():
    cells, train, evals = frames(seeds=2, hold=True)
    return joined(cells, train), joined(cells, evals)


@pytest.fixture(scope="module")
def failing():
    cells, train, evals = frames(seeds=2, hold=False, seed=1)
    return joined(cells, train), joined(cells, evals)


def test_combine__failure_dominates_then_missing_data():
    assert combine([HOLDS, HOLDS]) == HOLDS
    assert combine([HOLDS, NO_DATA]) == NO_DATA
    assert combine([NO_DATA, FAILS, HOLDS]) == FAILS
    assert combine([]) == NO_DATA


def test_claims__all_hold_on_tables_built_to_hold(holding):
    claims = all_claims(*holding)
    assert [c.key for c in claims] == KEYS
    for c in claims:
        assert c.verdict == HOLDS, (c.key, [k.numbers for k in c.checks])
        assert "bootstrap CI over seeds" in " ".join(k.test for k in c.checks) or c.key in (
            "convergence", "payload_ratio")


def test_claims__none_holds_on_tables_built_to_fail(failing):
    for c in all_claims(*failing):
        assert c.verdict == FAILS, (c.key, [k.numbers for k in c.checks])


def test_claims__single_seed_uses_mann_whitney_over_episodes():
    cells, train, evals = frames(seeds=1, hold=True, seed=2)
    tr, ev = joined(cells, train), joined(cells, evals)
    c = claim_hier_above_dec(tr)
    assert c.verdict == HOLDS
    assert all("Mann-Whitney" in k.test for k in c.checks)
    assert claim_above_ic3net(ev).verdict == HOLDS
    c = claim_hier_above_dec(joined(*frames(seeds=1, hold=False, seed=2)[:2]))
    assert c.verdict == FAILS


def test_claims__missing_configurations_are_not_enough_data(holding):
    train, evals = holding
    no_dec60 = train[~((train["method"] == "decentralized") & (train["n_robots"] == 60))]
    c = claim_hier_above_dec(no_dec60)
    assert c.verdict == NO_DATA
    assert [k.verdict for k in c.checks] == [HOLDS, HOLDS, NO_DATA]
    assert claim_gap_widens(no_dec60).verdict == NO_DATA
    assert claim_convergence(train[train["n_robots"] != 90]).verdict == NO_DATA
    assert claim_above_ic3net(evals[evals["method"] != "ic3net"]).verdict == NO_DATA
    assert claim_safety(evals[evals["loss_p"] != 0.2]).verdict == NO_DATA
    assert claim_payload_ratio(evals[evals["method"] != "hierarchical"]).verdict == NO_DATA
    empty_t, empty_e = train.iloc[0:0], evals.iloc[0:0]
    assert {c.verdict for c in all_claims(empty_t, empty_e)} == {NO_DATA}


def test_claims__too_short_training_is_not_enough_data():
    cells, train, _ = frames(seeds=1, episodes=20)
    c = claim_convergence(joined(cells, train))
    assert c.verdict == NO_DATA  # windows of 4 episodes


def _eval_rows(method: str, success: np.ndarray, n: int = 40, p: float = 0.2, cell: str = "") -> pd.DataFrame:
    return pd.DataFrame({"cell_id": cell or method, "episode": np.arange(len(success)),
                         "success_rate": success, "method": method, "n_robots": n, "loss_p": p,
                         "seed": 0, "groups": 4, "safety_filter": method == "hierarchical"})


def test_above_ic3net__higher_mean_but_crossing_curves_does_not_hold():
    # Hierarchical: two failed episodes, otherwise perfect; IC3Net: always 0.5. The mean is
    # higher (0.9 vs 0.5, significant) but the lowest 10% of episodes are below IC3Net.
    hier = np.r_[np.zeros(2), np.ones(18)]
    ic3 = np.full(20, 0.5)
    ev = pd.concat([_eval_rows("hierarchical", hier), _eval_rows("ic3net", ic3)])
    c = claim_above_ic3net(ev, ns=(40,), ps=(0.2,))
    assert c.verdict == FAILS
    assert "curve difference min -0.5" in c.checks[0].numbers
    ev2 = pd.concat([_eval_rows("hierarchical", np.full(20, 0.6)), _eval_rows("ic3net", ic3)])
    assert claim_above_ic3net(ev2, ns=(40,), ps=(0.2,)).verdict == HOLDS


def test_above_ic3net__identical_results_do_not_hold():
    ev = pd.concat([_eval_rows("hierarchical", np.ones(20)), _eval_rows("ic3net", np.ones(20))])
    assert claim_above_ic3net(ev, ns=(40,), ps=(0.2,)).verdict == FAILS


def _payload_rows(c_hier: float, n: int = 40, z: int = 4) -> pd.DataFrame:
    return pd.DataFrame({"cell_id": "h", "episode": np.arange(5), "payload_scalars_per_step": c_hier,
                         "payload_dec_per_step": n * (n - 1) * 3.0, "method": "hierarchical",
                         "n_robots": n, "loss_p": 0.2, "seed": 0, "groups": z, "safety_filter": True})


def test_payload_ratio__at_bound_holds_above_or_below_does_not():
    assert claim_payload_ratio(_payload_rows(40 * 3 * 3.0)).verdict == HOLDS
    assert claim_payload_ratio(_payload_rows(40 * 3 * 3.0 * 1.05)).verdict == FAILS  # above the bound
    assert claim_payload_ratio(_payload_rows(40 * 3 * 3.0 * 0.9)).verdict == FAILS  # not equal


def _safety_rows(coll: np.ndarray, corr: np.ndarray, n: int = 40) -> pd.DataFrame:
    return pd.DataFrame({"cell_id": "h", "episode": np.arange(len(coll)), "collision_rate": coll,
                         "correction_rate": corr, "method": "hierarchical", "n_robots": n,
                         "loss_p": 0.2, "seed": 0, "groups": 4, "safety_filter": True})


def test_safety__one_collision_or_corrections_near_8_percent_fail():
    z, c3 = np.zeros(30), np.full(30, 0.03)
    assert claim_safety(_safety_rows(z, c3), ns=(40,)).verdict == HOLDS
    one = z.copy()
    one[7] = 0.001
    assert claim_safety(_safety_rows(one, c3), ns=(40,)).verdict == FAILS
    rng = np.random.default_rng(0)
    near = 0.079 + rng.normal(0, 0.01, 30)  # mean just below 8%, CI reaching above it
    assert claim_safety(_safety_rows(z, near), ns=(40,)).verdict == FAILS


def test_claims_markdown__lists_every_claim_with_its_verdict(holding):
    md = claims_markdown(all_claims(*holding))
    for key in KEYS:
        assert f"## {key}" in md
    assert md.count("**Verdict: holds**") == len(KEYS)
    assert md.count("| **holds** |") == len(KEYS)
