"""The claims page: ``paper.claims.claims`` results as a DataFrame (one row per check) and as
Markdown, with the calibration table of the tests (``paper.claims.calibrate``) beside it.

Pure functions; ``reports.build`` writes the files.
"""
from __future__ import annotations

from collections.abc import Sequence

import pandas as pd
from scipy import stats as sps

from paper.claims.claims import Claim
from paper.claims.verdicts import NOT_ENOUGH, VERDICTS
from reports.stats import ALPHA

CHECK_COLUMNS = ["claim", "name", "scope", "configuration", "execution", "verdict", "verdict_words", "numbers",
                 "test", "power", "power_note", "estimate", "ci_lo", "ci_hi", "claim_region", "points", "ci_excludes"]
POOLED_COLUMNS = ["claim", "name", "scope", "toward", "against", "p_toward", "p_against", "verdict"]


def claims_frame(claims: Sequence[Claim]) -> pd.DataFrame:
    """One row per check: claim key, readable name, scope ("paper" or "run"),
    configuration, execution mode, verdict and its printed words, numbers, test, power (NaN
    for checks without one) and its note (the stated effect, the seeds 80% power would
    need); the estimate and its printed 95% interval, the claim's region of that quantity,
    which way the estimate points and what the interval excludes (``paper.claims.sides``)."""
    rows = [{"claim": c.key, "name": c.name, "scope": k.scope, "configuration": k.config,
             "execution": k.execution, "verdict": k.verdict, "verdict_words": k.verdict_words,
             "numbers": k.numbers, "test": k.test, "power": k.power, "power_note": k.power_text,
             "estimate": k.side.estimate, "ci_lo": k.side.lo, "ci_hi": k.side.hi,
             "claim_region": k.side.region() if k.side.known else "", "points": k.side.points,
             "ci_excludes": k.side.excludes}
            for c in claims for k in c.checks]
    return pd.DataFrame(rows, columns=CHECK_COLUMNS)


def pooled_frame(claims: Sequence[Claim]) -> pd.DataFrame:
    """One row per claim and scope with checks: the sign test across its checks
    (``paper.claims.pooled``): checks pointing toward and against, both p-values, verdict."""
    rows = []
    for c in claims:
        for scope in dict.fromkeys(k.scope for k in c.checks):
            p = c.pooled(scope)
            rows.append({"claim": c.key, "name": c.name, "scope": scope, "toward": p.toward,
                         "against": p.against, "p_toward": p.p_toward, "p_against": p.p_against,
                         "verdict": p.verdict})
    return pd.DataFrame(rows, columns=POOLED_COLUMNS)


def _by_mode(c: Claim, scope: str | None = None) -> str:
    return "; ".join(f"{m}: {v}" for m, v in c.verdict_by_mode(scope).items() if m != "-")


def claims_summary(claims: Sequence[Claim]) -> pd.DataFrame:
    """One row per claim: key, name, verdict at the paper's configurations, the same per
    execution mode ("argmax: supported; sample: undecided"), and the verdict at the
    run's own configurations ("" when not built with ``--claims-at run``)."""
    return pd.DataFrame([{"claim": c.key, "name": c.name, "verdict": c.verdict, "by_mode": _by_mode(c),
                          "verdict_run": c.verdict_at("run") or ""} for c in claims],
                        columns=["claim", "name", "verdict", "by_mode", "verdict_run"])


def _esc(s: object) -> str:
    return str(s).replace("|", "\\|")


def over_limit_markdown(cal: pd.DataFrame) -> list[str]:
    """Lines for each error rate of a store's calibration over the limit (a **NO**): its count
    out of the simulations and the exact one-sided binomial test of that count against 5%
    (``scipy.stats.binomtest``), which says whether the excess is Monte-Carlo error or the
    test's own (docs/decisions/0234). Nothing when every rate is within the limit."""
    out = []
    for _, r in cal.iterrows():
        for ok, rate, what in (("null_ok", "rate", "supported"), ("contra_ok", "contradicted", "contradicted")):
            if not bool(r[ok]):
                hits = int(round(float(r[rate]) * int(r["sims"])))
                p = sps.binomtest(hits, int(r["sims"]), ALPHA, alternative="greater").pvalue
                out.append(f"- {r['test']}, {r['check']} ({r['truth']}, {r['source']}): *{what}* "
                           f"{hits} of {r['sims']} ({float(r[rate]):.2%}); exact binomial test against "
                           f"{ALPHA:.0%}: p = {p:.2g}")
    if not out:
        return []
    return ["", "## Rates over the limit", "",
            "Each rate marked **NO**, with the exact binomial test of its count against 5% (scipy's "
            "`binomtest`, one-sided). A p-value far below 0.05 says the excess is the test's own at this "
            "run's spread, not Monte-Carlo error; the level stays what decision 0230 fixed "
            "(docs/decisions/0234).", "", *out]


def calibration_markdown(cal: pd.DataFrame, meta: dict | None = None, coverage: pd.DataFrame | None = None) -> str:
    """The calibration table: per test, scenario and seed count, the rate of
    ``supported`` with its Monte-Carlo standard error, and the rate of ``contradicted``
    (a column only when the calibration measured it)."""
    meta = meta or {}
    contra = "contradicted" in cal.columns
    lines = ["# Calibration of the claim tests", "",
             "Simulated tables with known truth pushed through the claims' own functions "
             "(`bench calibrate`). *null*: the claim is false (at its boundary); the rate of "
             "`supported` must be <= 5% + Monte-Carlo error. *effect*: the claim is true with the "
             "stated effect; the rate is the power."
             + (" Where the claim holds (effect) or sits at its boundary, the rate of `contradicted` "
                "must be <= 5% + Monte-Carlo error too. A *family* is a whole claim over several "
                "configurations and execution modes (its verdict, not one check)." if contra else ""), ""]
    if "check" in cal.columns:
        lines[2] = ("Every check of every statistical claim at its own seed counts and Bonferroni level "
                    "(k = the claim's checks), and every claim as a whole, simulated on per-seed values "
                    "drawn from the run's own spread (`bench calibrate`, paper/claims/calibrate_data.py): "
                    "*resampled* from the claim's pooled standardized seed residuals (smoothed "
                    "bootstrap), *normal* the stated parametric case, each group at its own observed "
                    "s.d. *null*: the claim at its boundary (a whole claim: its first check at the "
                    "boundary and the rest true, or every check at the boundary); the rates of "
                    "`supported` and of `contradicted` must each be <= 5% + 2 MC s.e. *effect*: the "
                    "stated effect; the rate of `supported` is the power, that of `contradicted` must "
                    "stay within the limit.")
    if meta:
        lines += [", ".join(f"{k}: {v}" for k, v in meta.items()), ""]
    data = "check" in cal.columns  # the calibration on a store's own spread (paper.claims.calibrate_data)
    head = (["test", "check", "truth", "source", "seeds", "k", "sims", "rate supported", "MC s.e."] if data
            else ["test", "truth", "scenario", "seeds", "sims", "rate supported", "MC s.e."])
    head += (["rate contradicted", "MC s.e. ", "ok"] if data else ["rate contradicted", "ok"] if contra else ["ok"])
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for _, r in cal.iterrows():
        fine = bool(r["null_ok"]) and (not contra or bool(r["contra_ok"]))
        checked = r["truth"] == "null" or contra
        ok = "" if not checked else ("yes" if fine else "**NO**")
        if data:
            cells = [r["test"], r["check"], r["truth"], r["source"], r["seeds"], r["k"], r["sims"],
                     f"{r['rate']:.4f}", f"{r['mc_se']:.4f}", f"{r['contradicted']:.4f}", f"{r['contra_se']:.4f}", ok]
        else:
            cells = [r["test"], r["truth"], r["scenario"], r["seeds"], r["sims"], f"{r['rate']:.3f}",
                     f"{r['mc_se']:.3f}"] + ([f"{r['contradicted']:.3f}"] if contra else []) + [ok]
        lines.append("| " + " | ".join(_esc(x) for x in cells) + " |")
    if data:
        lines += over_limit_markdown(cal)
    if coverage is not None and len(coverage):
        lines += ["", "## Coverage of the 95% intervals", "",
                  "Simulated coverage of the true mean by each interval at the seed counts and spreads "
                  "given (`bench calibrate`); the intervals the reports print must reach 93%: a headline row "
                  "whose interval does not prints 'interval not trusted' instead (docs/decisions/0233).", "",
                  "| " + " | ".join(map(str, coverage.columns)) + " |", "|" + "---|" * len(coverage.columns)]
        lines += ["| " + " | ".join(_esc(f"{v:.3f}" if isinstance(v, float) else v) for v in r) + " |"
                  for r in coverage.itertuples(index=False)]
    return "\n".join(lines) + "\n"


def claims_markdown(claims: Sequence[Claim], calibration_link: str | None = None,
                    calibration_own: bool = True) -> str:
    """The claims page: a verdict table with each claim's pooled sign test, then per claim
    the statement, the test, the pooled test and one row per configuration and execution
    mode. ``calibration_own``: whether the linked calibration is this run's own (its
    ``meta.run``)."""
    own = [c for c in claims if c.home != "paper"]  # claims of the run's own methods (method_claims)
    paper = [c for c in claims if c.home == "paper"]
    run_scope = any(k.scope == "run" for c in paper for k in c.checks)
    lines = ["# Claims of the paper's Sec. IV against this run", "",
             "Verdicts: " + ", ".join(f"**{v}**" for v in VERDICTS) + ". Tests take the seed as "
             "the unit (per-seed means, Welch / one-sample t, level 0.0125 = 0.05 / 4, the rule of "
             "docs/decisions/0230, fixed before the data and never refitted to a run); fewer than 3 seeds on a "
             "side is **not enough seeds**, whatever the data. A claim is supported when every "
             "check is (each at 0.0125), and contradicted when one check is at 0.0125 / k, k being the "
             "claim's number of checks (Bonferroni). An **undecided** check says which way its "
             "estimate points (toward the claim or against it) and what its printed 95% interval "
             "excludes (the claim, its negation, or neither); only one whose interval spans both the "
             "claim and its negation, with power under 50% to detect the stated effect, reads "
             "*undecided: this design could not have decided it*. Beside each check: its power, at its "
             "own seed counts and observed spread, and the seeds per side that 80% power would need. "
             "Beside each claim: its **pooled test**, an exact sign test (scipy's `binomtest`) on how "
             "many of its checks point toward the claim, one-sided at 0.0125 each way: whether the "
             "claim's direction holds across its configurations.", ""]
    if calibration_link:
        whose = ("this run's own, at its seed counts" if calibration_own
                 else "**not this run's own** (its meta names another run): rebuild it with `bench calibrate --run`")
        lines += [f"How often each test, and each pooled test, says *supported* when the claim is false, its "
                  f"power, and how often it says *contradicted* when the claim holds: "
                  f"[calibration]({calibration_link}) ({whose}).", ""]
    else:
        lines += ["This run has no calibration of its own yet (`bench calibrate --run RUN --out "
                  "RUN/report/calibration.json`).", ""]
    head = "| claim | name | verdict (paper configurations) | per execution mode | pooled sign test |"
    lines += [head + (" verdict (run configurations) |" if run_scope else ""),
              "|---|---|---|---|---|" + ("---|" if run_scope else "")]
    for c in paper:
        row = (f"| [{c.key}](#{c.key}) | {_esc(c.name)} | **{c.verdict}** | {_esc(_by_mode(c)) or '-'} | "
               f"{_esc(c.pooled().text())} |")
        lines.append(row + (f" {c.verdict_at('run') or '-'} |" if run_scope else ""))
    if own:
        lines += ["", "## Methods of this run above each baseline", "",
                  "Each method of the run that is neither the paper's method nor a baseline (its "
                  "`paper_role`), checked against every baseline of the run at every configuration "
                  "both ran, per execution mode: the same one-sided Welch t over per-seed means at "
                  "0.0125, contradicted at 0.0125 / k over the claim's k checks, power beside each "
                  "check, and calibrated with the paper's claims (the family `above_baselines`).", "",
                  "| claim | name | verdict (run configurations) | per execution mode | pooled sign test |",
                  "|---|---|---|---|---|"]
        lines += [f"| [{c.key}](#{c.key}) | {_esc(c.name)} | **{c.verdict}** | {_esc(_by_mode(c)) or '-'} | "
                  f"{_esc(c.pooled().text())} |" for c in own]
    for c in claims:
        lines += ["", f"## {c.key}", "", f"**{_esc(c.name)}**", "",
                  f"*{'Paper' if c.home == 'paper' else 'Claim'}:* {c.statement}", "",
                  f"*Test:* {c.criterion}", "", f"**Verdict: {c.verdict}**", "",
                  f"*Pooled across its checks:* {c.pooled().text()}", "",
                  "| scope | configuration | execution | verdict | numbers | test | power |",
                  "|---|---|---|---|---|---|---|"]
        lines += [f"| {k.scope} | {_esc(k.config)} | {_esc(k.execution)} | {k.verdict_words} | "
                  f"{_esc(k.numbers)} | {_esc(k.test)} | {_esc(k.power_text)} |" for k in c.checks]
    return "\n".join(lines) + "\n"


def claims_table_markdown(claims: Sequence[Claim]) -> str:
    """The compact claims table the README's Reproduction section embeds
    (``claims_table.md``): one row per checked configuration and execution mode at the
    paper's configurations (claim, the paper's statement, configuration, mode, our numbers
    with their 95% CI, verdict), the claim's name and statement on its first row only;
    configurations without enough seeds are counted under the table instead of listed."""
    lines = ["| claim | paper | configuration | execution | our numbers (95% CI) | verdict | power |",
             "|---|---|---|---|---|---|---|"]
    missing: dict[str, int] = {}
    for c in claims:
        first = True
        for k in c.checks:
            if k.scope != "paper":
                continue
            if k.verdict == NOT_ENOUGH:
                missing[c.key] = missing.get(c.key, 0) + 1
                continue
            who = f"**{_esc(c.name)}** | {_esc(c.statement)}" if first else " | "  # once per claim
            lines.append(f"| {who} | {_esc(k.config)} | {_esc(k.execution)} | {_esc(k.numbers)} | "
                         f"**{k.verdict_words}** | {_esc(k.power_text)} |")
            first = False
    pooled = [(c, c.pooled()) for c in claims if c.home == "paper"]
    pooled = [(c, p) for c, p in pooled if p.toward + p.against > 1]
    if pooled:
        lines += ["", "Pooled across configurations (exact sign test on the directions of the checks' estimates, "
                  "one-sided at 0.0125 each way):", "", "| claim | pooled sign test |", "|---|---|"]
        lines += [f"| {_esc(c.name)} | {_esc(p.text())} |" for c, p in pooled]
    if missing:
        lines += ["", "Not enough seeds yet (checks per claim): "
                  + ", ".join(f"`{key}` {n}" for key, n in missing.items()) + "."]
    return "\n".join(lines) + "\n"
