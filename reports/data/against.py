"""``bench report --run MINE --against REF``: report a run together with the committed cells
of another run (e.g. ``reproduction/paper``) at the configurations MINE covers, so a new
method is compared with the published baselines without retraining them.

The merge is allowed only when the two runs evaluated the same scenarios under the same
settings, checked in this order (the first mismatch is one BenchError line):

1. every configuration (N, p) MINE holds a done cell at must have done cells in REF;
2. the settings that decide what an evaluation episode is must agree between MINE's cells
   and REF's cells at that configuration: layout, horizon, groups, on_goal, loss model,
   evaluation episodes, and the training budget (episodes) between learned cells
   (a planner trains nothing);
3. paired episodes, (N, p, seed, episode) present in both runs, must carry equal
   ``scenario`` hashes (starts and goals; algorithms/common/episodes.py), and every
   configuration must have at least one pair.

REF cells whose id MINE already holds are MINE's (one row per cell). Where MINE re-ran one of
REF's methods with other settings, MINE's cells are the headline and REF's the labelled
variant (reports/data/variants.py). Nothing is written to
REF; the merged report goes to MINE/report (or ``--out``) and says what it merged.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from bench.store.completeness import row_cell_rows
from bench.store.run_store import RunStore
from envs.errors import BenchError
from reports.data.store import Store, fmt_p, load_store
from reports.data.variants import MERGED

SETTINGS = ("layout", "horizon", "groups", "on_goal", "loss_model", "eval_episodes")
PAIR = ["n_robots", "loss_p", "seed", "episode"]


def _configs(cells: pd.DataFrame) -> list[tuple[int, float]]:
    return sorted({(int(n), round(float(p), 9)) for n, p in cells[["n_robots", "loss_p"]].to_numpy()})


def _at(df: pd.DataFrame, n: int, p: float) -> pd.DataFrame:
    return df[(df["n_robots"] == n) & np.isclose(df["loss_p"].astype(float), p)]


def _learned(cells: pd.DataFrame) -> pd.DataFrame:
    return cells[~cells["executions"].astype(str).str.split(",").map(lambda m: "planner" in m)]


def check_compatible(mine: Store, ref: Store, ref_name: str) -> None:
    """BenchError naming the first configuration, setting or scenario where ``ref`` cannot
    stand beside ``mine`` (see the module docstring)."""
    check_cell_lists(mine.done, ref.done, ref_name)
    _check_scenarios(mine, ref, ref_name)


def check_cell_lists(mine_done: pd.DataFrame, ref_done: pd.DataFrame, ref_name: str) -> None:
    """Checks 1 and 2 of the module docstring on the two runs' done cells alone (rows of
    cells.parquet): ``bench report`` runs them before it loads any training or evaluation
    row, so a mismatch is refused in a second."""
    if mine_done.empty:
        raise BenchError(f"--against {ref_name}: the run has no done cell to compare")
    for n, p in _configs(mine_done):
        theirs, ours = _at(ref_done, n, p), _at(mine_done, n, p)
        where = f"N={n} p={fmt_p(p)}"
        if theirs.empty:
            raise BenchError(f"--against {ref_name}: it has no done cell at {where}, which this run covers")
        for field in SETTINGS:
            a, b = sorted(set(map(str, ours[field]))), sorted(set(map(str, theirs[field])))
            if a != b:
                raise BenchError(f"--against {ref_name}: {field} differs at {where}: "
                                 f"{', '.join(a)} here, {', '.join(b)} there")
        ea = sorted({int(v) for v in _learned(ours)["episodes"]})
        eb = sorted({int(v) for v in _learned(theirs)["episodes"]})
        if ea and eb and ea != eb:
            raise BenchError(f"--against {ref_name}: training episodes differ at {where}: "
                             f"{', '.join(map(str, ea))} here, {', '.join(map(str, eb))} there")


def _check_scenarios(mine: Store, ref: Store, ref_name: str) -> None:
    """Check 3 of the module docstring: paired evaluation episodes ran equal scenarios."""
    ours = mine.eval[PAIR + ["scenario"]].drop_duplicates(PAIR)
    theirs = ref.eval[PAIR + ["scenario"]].drop_duplicates(PAIR)
    pairs = ours.merge(theirs, on=PAIR, suffixes=("", "_ref"))
    bad = pairs[pairs["scenario"] != pairs["scenario_ref"]]
    if len(bad):
        r = bad.sort_values(PAIR).iloc[0]
        raise BenchError(f"--against {ref_name}: scenario differs at N={int(r.n_robots)} p={fmt_p(r.loss_p)} "
                         f"seed {int(r.seed)} episode {int(r.episode)}: {r.scenario} here, {r.scenario_ref} "
                         "there (another layout, evaluation chunk size or code version)")
    for n, p in _configs(mine.done):
        if _at(pairs, n, p).empty:
            raise BenchError(f"--against {ref_name}: no paired evaluation episode at N={n} p={fmt_p(p)} "
                             "(the two runs share no seed there)")


def _unusable_files(ref: Store) -> list[str]:
    """What ``load_store`` left out of ``ref`` for a file, each naming it: a damaged or
    misplaced file, a done cell's absent eval file (D17: a refusal names its file), the
    latter told by the one completeness rule (``bench.store.completeness.cell_rows``)."""
    out = [p.removeprefix("skipped ") for p in ref.problems if p.startswith("skipped ")]
    store = RunStore(ref.run_dir)
    for row in ref.done.to_dict("records"):
        try:
            rows = row_cell_rows(store, row)
        except (BenchError, ImportError, KeyError, ValueError):  # already among the problems above
            continue
        if rows.expected.eval and not rows.eval_file:
            cid = row["cell_id"]
            out.append(f"eval/{cid}.parquet is absent although cells.parquet says cell {cid} is done; "
                       "rerun `bench run` on that run to evaluate it again")
    return out


def merge_against(mine: Store, ref_dir: Path | str) -> Store:
    """``mine`` plus the done cells (and their rows) of the run at ``ref_dir`` at the
    configurations ``mine`` covers; BenchError when they are not comparable."""
    ref = load_store(ref_dir)
    try:
        check_compatible(mine, ref, str(ref_dir))
    except BenchError as exc:
        unusable = _unusable_files(ref)
        if not unusable:
            raise
        more = f" ({len(unusable) - 1} more)" if len(unusable) > 1 else ""
        raise BenchError(f"{exc}; in {ref_dir}, {unusable[0]}{more}") from None
    keep = set()
    for n, p in _configs(mine.done):
        keep |= set(_at(ref.done, n, p)["cell_id"])
    keep -= set(mine.cells["cell_id"])
    cells = ref.cells[ref.cells["cell_id"].isin(keep)]
    note = (f"merged with {len(cells)} done cells of {ref_dir} (bench report --against) at the "
            f"{len(_configs(mine.done))} configurations this run covers; settings and the scenarios of "
            "paired evaluation episodes verified equal; where this run re-ran a method of "
            f"{ref_dir} with other settings, this run's cells are the headline (leaderboard, figures, "
            "Table I, claims) and the merged ones a variant labelled by how they differ")
    merged = pd.concat([mine.cells.assign(**{MERGED: False}), cells.assign(**{MERGED: True})], ignore_index=True)
    return Store(mine.run_dir, merged,
                 pd.concat([mine.train, ref.train[ref.train["cell_id"].isin(keep)]], ignore_index=True),
                 pd.concat([mine.eval, ref.eval[ref.eval["cell_id"].isin(keep)]], ignore_index=True),
                 mine.manifest, [*mine.problems, note])
