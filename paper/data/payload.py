"""The payload points behind Fig. 3 and the payload-ratio claim: per hierarchical (N, Z),
the accounted C_hier, C_dec, their ratio and the bound (Z-1)/(N-1) of Sec. III-A (the
inequality after eq:gru_pred_loss), at the p of Fig. 3 when the run has it, else over every p.

May import: paper.settings, reports.data.store.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from paper.settings import PAPER_FIG3_P
from reports.data.store import fmt_p, select

__all__ = ["payload_points"]


def payload_points(evals: pd.DataFrame) -> pd.DataFrame:
    """One row per hierarchical (N, Z): measured C_hier, C_dec, ratio and bound.

    Columns: n_robots, groups, d_m, c_hier, c_dec, c_dec_source ("decentralized" or
    "reference"), ratio, ratio_max (largest per-episode C_hier / reference C_dec), bound
    ((Z-1)/(N-1)), c_hier_bound (N (Z-1) d_m), episodes, p_used.
    """
    cols = ["n_robots", "groups", "d_m", "c_hier", "c_dec", "c_dec_source", "ratio", "ratio_max",
            "bound", "c_hier_bound", "episodes", "p_used"]
    ev = evals
    if any(np.isclose(PAPER_FIG3_P, q) for q in ev["loss_p"].dropna().astype(float)):
        ev = select(ev, loss_p=PAPER_FIG3_P)
        p_used = fmt_p(PAPER_FIG3_P)
    else:
        p_used = "all"
    hier = select(ev, "hierarchical")
    dec = select(ev, "decentralized")
    out = []
    for (n, z), g in hier.groupby(["n_robots", "groups"], sort=True):
        n, z = int(n), int(z)
        ref = g["payload_dec_per_step"].to_numpy(dtype=np.float64)
        c_hier = float(g["payload_scalars_per_step"].mean())
        d = dec[dec["n_robots"] == n]["payload_scalars_per_step"]
        c_dec, source = (float(d.mean()), "decentralized") if len(d) else (float(np.mean(ref)), "reference")
        d_m = float(np.mean(ref)) / (n * (n - 1)) if n > 1 else float("nan")
        with np.errstate(divide="ignore", invalid="ignore"):
            per_ep = g["payload_scalars_per_step"].to_numpy(dtype=np.float64) / ref
        out.append({
            "n_robots": n, "groups": z, "d_m": d_m, "c_hier": c_hier, "c_dec": c_dec,
            "c_dec_source": source, "ratio": c_hier / c_dec if c_dec > 0 else float("nan"),
            "ratio_max": float(np.nanmax(per_ep)) if np.isfinite(per_ep).any() else float("nan"),
            "bound": (z - 1) / (n - 1) if n > 1 else float("nan"),
            "c_hier_bound": n * (z - 1) * d_m, "episodes": len(g), "p_used": p_used,
        })
    return pd.DataFrame(out, columns=cols)
