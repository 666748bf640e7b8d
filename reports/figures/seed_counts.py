"""Seed counts per configuration, in words, for figure captions.

A caption must say exactly which configurations have how many seeds: "3/5 seeds" does
not say which have 5. ``seed_counts`` counts the cells (seeds) per configuration and
``counts_text`` groups configurations by count: "3 seeds at N = 80, 90, 100 and 5 seeds
at N = 20, 40, 60", or "N = 40, 60 (p = 0.2)" for (N, p) panels. Pure functions.
"""
from __future__ import annotations

from collections.abc import Iterable

import pandas as pd

from reports.figures.plotting import fmt_list


def seed_counts(rows: pd.DataFrame, keys: Iterable[str] = ("n_robots", "loss_p"),
                unit: str = "cell_id") -> dict[tuple[float, ...], int]:
    """Configuration (values of ``keys``) -> number of distinct ``unit`` values (seeds)."""
    keys = list(keys)
    if rows.empty:
        return {}
    per = rows.groupby(keys, sort=True)[unit].nunique()
    return {tuple(float(v) for v in (k if isinstance(k, tuple) else (k,))): int(c) for k, c in per.items()}


def _configs_text(configs: list[tuple[float, ...]]) -> str:
    """(N,) or (N, p) configurations as "N = 20, 40" or "N = 40, 60 (p = 0.2, 0.4)"."""
    if all(len(c) == 1 for c in configs):
        return f"N = {fmt_list(sorted(c[0] for c in configs))}"
    by_p: dict[float, list[float]] = {}
    for n, p in configs:
        by_p.setdefault(p, []).append(n)
    groups: dict[tuple[float, ...], list[float]] = {}  # the same team sizes at several p
    for p, ns in sorted(by_p.items()):
        groups.setdefault(tuple(sorted(ns)), []).append(p)
    return ", ".join(f"N = {fmt_list(ns)} (p = {fmt_list(ps)})" for ns, ps in groups.items())


def counts_text(counts: dict[tuple[float, ...], int], noun: str = "seed") -> str:
    """Each count with the configurations that have it, fewest seeds first: "3 seeds at
    N = 80, 90 and 5 seeds at N = 20" (every configuration is named, even with one count)."""
    if not counts:
        return f"no {noun}s"
    by_count: dict[int, list[tuple[float, ...]]] = {}
    for cfg, c in counts.items():
        by_count.setdefault(c, []).append(cfg)

    def word(c: int) -> str:
        return f"{c} {noun}" + ("" if c == 1 else "s")

    return " and ".join(f"{word(c)} at {_configs_text(cfgs)}" for c, cfgs in sorted(by_count.items()))
