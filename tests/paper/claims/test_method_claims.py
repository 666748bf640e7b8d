"""Claims of a run's own methods, "M above each baseline" (paper/claims/method_claims.py):
roles from ``Method.paper_role``, one check per baseline x configuration x execution-mode
pair, Bonferroni over the claim's checks, power beside each, and the claims page's section.
Runtime: about 3 s."""
from __future__ import annotations

import numpy as np
import pandas as pd

from algorithms.base import BASELINE, REFERENCE
from algorithms.registry import method_class
from paper.claims.claims import claim_above_ic3net
from paper.claims.method_claims import (
    claim_above_baselines,
    method_claims,
    methods_by_role,
    paper_role,
)
from paper.claims.page import claims_frame, claims_markdown
from paper.claims.verdicts import CONTRADICTED, NOT_ENOUGH, SUPPORTED, TEST_ALPHA

LEARNED = ("argmax", "sample")


def _evals(levels: dict[str, float], seeds: int = 5, configs=((20, 0.2),), episodes: int = 10,
           seed: int = 0) -> pd.DataFrame:
    """Evaluation rows: per method, seed and configuration, success around ``levels[m]``;
    pibt and names ending in "_planner" in mode planner, the others in two learned modes."""
    rng = np.random.default_rng(seed)
    parts = []
    for m, level in levels.items():
        modes = ("planner",) if m == "pibt" or m.endswith("_planner") else LEARNED
        for n, p in configs:
            for s in range(seeds):
                for mode in modes:
                    parts.append(pd.DataFrame({
                        "cell_id": f"{m}-{n}-{p}-{s}", "episode": np.arange(episodes), "method": m,
                        "n_robots": n, "loss_p": p, "execution": mode,
                        "success_rate": np.clip(level + rng.normal(0, 0.03) + rng.normal(0, 0.05, episodes), 0, 1)}))
    return pd.concat(parts, ignore_index=True)


def test_built_ins_declare_their_role_and_other_methods_are_the_runs_own() -> None:
    assert method_class("hierarchical").paper_role == REFERENCE
    assert {method_class(m).paper_role for m in ("decentralized", "ic3net", "pibt")} == {BASELINE}
    assert paper_role("not_installed") == ""  # cannot be resolved here: a method of the run's own
    ev = _evals({"mine": 0.5, "pibt": 0.5, "hierarchical": 0.5, "decentralized": 0.5, "other": 0.5})
    assert methods_by_role(ev) == (["decentralized", "pibt"], ["mine", "other"])


def test_one_check_per_baseline_configuration_and_mode_pair_decided_with_bonferroni() -> None:
    ev = _evals({"mine": 0.8, "decentralized": 0.4, "pibt": 0.5}, configs=((20, 0.2), (40, 0.2)))
    (claim,) = method_claims(ev)
    assert claim.key == "above_baselines_mine" and claim.home == "run"
    got = [(k.config, k.execution) for k in claim.checks]
    assert got == [("vs Decentralized, N = 20, p = 0.2", "argmax"), ("vs Decentralized, N = 20, p = 0.2", "sample"),
                   ("vs Decentralized, N = 40, p = 0.2", "argmax"), ("vs Decentralized, N = 40, p = 0.2", "sample"),
                   ("vs PIBT, N = 20, p = 0.2", "argmax vs planner"), ("vs PIBT, N = 20, p = 0.2", "sample vs planner"),
                   ("vs PIBT, N = 40, p = 0.2", "argmax vs planner"), ("vs PIBT, N = 40, p = 0.2", "sample vs planner")]
    assert {k.scope for k in claim.checks} == {"run"}
    assert claim.verdict == SUPPORTED and claim.verdict_at("paper") is None
    assert all(f"level {TEST_ALPHA / 8:.2g} (Bonferroni)" in k.test for k in claim.checks)
    assert all(0.0 <= k.power <= 1.0 and "+0.1 mean success" in k.power_text for k in claim.checks)


def test_a_planner_of_the_runs_own_is_checked_against_each_mode_of_a_learned_baseline() -> None:
    claim = claim_above_baselines(_evals({"my_planner": 0.3, "decentralized": 0.6}), "my_planner", ["decentralized"])
    assert [k.execution for k in claim.checks] == ["planner vs argmax", "planner vs sample"]
    assert claim.verdict == CONTRADICTED


def _fixed(values: dict[str, np.ndarray], configs, modes) -> pd.DataFrame:
    """Rows whose every episode of a seed has that seed's value (per-seed means exact)."""
    return pd.concat([pd.DataFrame({"cell_id": f"{m}-{n}-{s}", "episode": np.arange(4), "method": m, "n_robots": n,
                                    "loss_p": p, "execution": mode, "success_rate": v})
                      for m, vs in values.items() for n, p in configs for s, v in enumerate(vs) for mode in modes],
                     ignore_index=True)


def test_the_contradiction_level_is_the_claims_bonferroni_level() -> None:
    # The baseline above by a one-sided p = 0.0057: a contradiction as one check (< 0.0125),
    # not in a claim of four checks (> 0.0125 / 4).
    mine = np.array([0.50, 0.53, 0.47, 0.51])
    values = {"mine": mine, "decentralized": mine + 0.06 + np.array([0.01, -0.01, 0.0, 0.005])}
    one = claim_above_baselines(_fixed(values, [(20, 0.2)], ["argmax"]), "mine", ["decentralized"])
    four = claim_above_baselines(_fixed(values, [(20, 0.2), (40, 0.2)], LEARNED), "mine", ["decentralized"])
    assert one.checks[0].verdict == CONTRADICTED
    assert len(four.checks) == 4 and four.checks[0].numbers == one.checks[0].numbers
    assert {k.verdict for k in four.checks} == {"undecided"}


def test_too_few_seeds_and_no_baseline() -> None:
    claim = claim_above_baselines(_evals({"mine": 0.9, "decentralized": 0.1}, seeds=2), "mine", ["decentralized"])
    assert {k.verdict for k in claim.checks} == {NOT_ENOUGH}
    assert method_claims(_evals({"mine": 0.9, "other": 0.1})) == []  # no baseline in the run
    assert method_claims(_evals({"hierarchical": 0.9, "decentralized": 0.1})) == []  # no method of its own


def test_claims_page_adds_the_runs_methods_and_keeps_the_papers_page() -> None:
    ev = _evals({"mine": 0.8, "decentralized": 0.4})
    paper = [claim_above_ic3net(ev)]  # a paper claim, without data here
    mine = method_claims(ev)
    page = claims_markdown(paper + mine)
    assert page.startswith(claims_markdown(paper).split("\n## above_ic3net")[0])
    assert "## Methods of this run above each baseline" in page
    assert ("| [above_baselines_mine](#above_baselines_mine) | mine above each baseline (mean success) "
            "| **supported** |") in page
    assert "## above_baselines_mine" in page and "*Claim:* mine is a method of this run" in page
    assert "Methods of this run" not in claims_markdown(paper)
    frame = claims_frame(paper + mine)
    assert (frame[frame["claim"] == "above_baselines_mine"]["scope"] == "run").all()


def test_each_check_reads_both_methods_at_its_own_loss_rate_and_names_its_quantity() -> None:
    # mine above the baseline at p = 0.2, below it at p = 0.6: pooled over p, both would agree
    ev = pd.concat([_evals({"mine": 0.8, "decentralized": 0.4}, configs=((20, 0.2),)),
                    _evals({"mine": 0.2, "decentralized": 0.7}, configs=((20, 0.6),), seed=1)], ignore_index=True)
    claim = claim_above_baselines(ev, "mine", ["decentralized"])
    got = {(k.config, k.execution): k.verdict for k in claim.checks}
    assert got == {("vs Decentralized, N = 20, p = 0.2", m): SUPPORTED for m in LEARNED} | {
        ("vs Decentralized, N = 20, p = 0.6", m): CONTRADICTED for m in LEARNED}
    assert all("mean success" in k.numbers for k in claim.checks)
    # each side's own seeds at that p: 5 vs 5, not the baseline's 10 over both loss rates
    assert all("(5 vs 5 seeds)" in k.test for k in claim.checks)
    assert claim.criterion.startswith("Per seed, the mean success rate over the evaluation episodes; Welch t")


def test_a_learned_method_with_one_mode_is_checked_in_the_mode_both_share_only() -> None:
    ev = _evals({"mine": 0.8, "decentralized": 0.4})
    ev = ev[(ev["method"] != "mine") | (ev["execution"] == "argmax")]  # mine evaluated in argmax only
    claim = claim_above_baselines(ev, "mine", ["decentralized"])
    assert [k.execution for k in claim.checks] == ["argmax"]  # not argmax against each baseline mode
