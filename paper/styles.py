"""The look of the paper's methods in every report figure: "Hierarchical (ours)" blue
first, then its baselines, then PIBT (seaborn's colour-blind palette; distinct line
styles so the lines stay apart in greyscale). Registered in the entry-point group
``warehouse_marl_bench.styles`` (reports/figures/styles.py)."""
from __future__ import annotations

from reports.figures.styles import Style

__all__ = ["STYLES"]

STYLES = {
    "hierarchical": Style("#0173b2", "-", 0),
    "decentralized": Style("#de8f05", "--", 1),
    "ic3net": Style("#029e73", "-.", 2),
    "pibt": Style("#949494", ":", 3),
}
