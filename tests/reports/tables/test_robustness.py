"""Robustness of training and every seed's outcome (reports/tables/robustness.py)."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from reports.tables.robustness import robustness_frame, seeds_frame, seeds_markdown


def _store() -> tuple[pd.DataFrame, pd.DataFrame, pd.Series]:
    """Decentralized at N = 8, p = 0.2: three seeds of the default variant (one collapsed,
    one whose return falls) and two of a mappo variant; PIBT (no training)."""
    cells = [("a0", 0, ""), ("a1", 1, ""), ("a2", 2, ""), ("m0", 0, "protocol=mappo"), ("m1", 1, "protocol=mappo")]
    success = {"a0": 0.04, "a1": 0.9, "a2": 0.7, "m0": 0.6, "m1": 0.8}
    train, evals = [], []
    for cid, seed, _ in cells:
        curve = np.linspace(0, -10, 100) if cid == "a1" else np.linspace(-10, 0, 100)
        train += [{"cell_id": cid, "method": "decentralized", "n_robots": 8, "episode": e, "team_return": r}
                  for e, r in enumerate(curve)]
        for mode, shift in (("argmax", 0.0), ("sample", 0.05)):
            evals += [{"cell_id": cid, "method": "decentralized", "n_robots": 8, "loss_p": 0.2, "seed": seed,
                       "execution": mode, "episode": k, "success_rate": success[cid] + shift} for k in range(4)]
    evals += [{"cell_id": "p0", "method": "pibt", "n_robots": 8, "loss_p": 0.2, "seed": 0, "execution": "planner",
               "episode": 0, "success_rate": 1.0}]
    variants = pd.Series({cid: v for cid, _, v in cells} | {"p0": ""})
    return pd.DataFrame(train), pd.DataFrame(evals), variants


def test_robustness_keeps_variants_apart() -> None:
    train, evals, variants = _store()
    frame = robustness_frame(train, evals, variants).set_index("label")
    default, mappo = frame.loc["Decentralized"], frame.loc["Decentralized [protocol=mappo]"]
    assert (default.seeds, default.collapsed, default.falling, default.curves) == (3, 1, 1, 3)
    assert (mappo.seeds, mappo.collapsed, mappo.falling) == (2, 0, 0)
    assert "PIBT" not in frame.index  # a planner has no training


def test_robustness__a_seed_is_collapsed_by_its_sample_success_not_by_an_argmax_livelock() -> None:
    """A seed that livelocks in argmax (2%) but succeeds when sampled (70%) trained well; one
    below 10% in sample execution collapsed. Without a sample evaluation, the first mode judges."""
    rates = {"ok": (0.02, 0.7), "bad": (0.05, 0.05), "fine": (0.9, 0.9)}
    train = pd.DataFrame([{"cell_id": c, "method": "hierarchical", "n_robots": 8, "episode": e, "team_return": float(e)}
                          for c in rates for e in range(60)])
    evals = pd.DataFrame([{"cell_id": c, "method": "hierarchical", "n_robots": 8, "loss_p": 0.2, "seed": k,
                           "execution": mode, "episode": 0, "success_rate": r[i]}
                          for k, (c, r) in enumerate(rates.items()) for i, mode in enumerate(("argmax", "sample"))])
    assert robustness_frame(train, evals).iloc[0].collapsed == 1
    argmax_only = evals[evals["execution"] == "argmax"]
    assert robustness_frame(train, argmax_only).iloc[0].collapsed == 2  # no sample to tell "ok"'s livelock apart
    assert robustness_frame(train, evals.assign(execution=evals["execution"].replace("sample", "sample@0.5"))
                            ).iloc[0].collapsed == 2  # argmax first again


def test_seeds_lists_every_seed_in_seed_order_with_its_spread() -> None:
    train, evals, variants = _store()
    frame = seeds_frame(train, evals, variants)
    row = frame[(frame.label == "Decentralized") & (frame.execution == "argmax")].iloc[0]
    assert row.success_by_seed == "4.0%, 90.0%, 70.0%"
    assert row["mean"] == pytest.approx((0.04 + 0.9 + 0.7) / 3)
    assert row.sd_pp == pytest.approx(100 * np.std([0.04, 0.9, 0.7], ddof=1))
    assert (row["min"], row.collapsed, row.falling) == (pytest.approx(0.04), 1, 1)
    assert list(frame[frame.label == "Decentralized"].execution) == ["argmax", "sample"]
    sample = frame[(frame.label == "Decentralized [protocol=mappo]") & (frame.execution == "sample")].iloc[0]
    assert sample.success_by_seed == "65.0%, 85.0%" and sample.collapsed == 0
    assert "| Decentralized [protocol=mappo] | 8 | 0.2 | argmax | 60.0%, 80.0% |" in seeds_markdown(frame)
