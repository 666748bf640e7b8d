#!/usr/bin/env bash
# The worked outside packages run end to end as a user runs them (README "Bring your own
# method", docs/extending.md), with no edit to this package:
#   examples/external_method  pip-installed, its methods registered by entry point;
#   examples/module_path      not installed, named as module:Class on PYTHONPATH.
# Each goes through bench methods, its contract tests, bench run, bench report (also
# --against reproduction/paper), bench tune and bench eval; their claims ("M above each
# baseline") must be on the claims pages; at the end, no tracked file of this package
# differs from before. `make example-check`; .ci/run calls it.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV="${VENV:-.venv}"
BENCH="$VENV/bin/bench"
OUT="${EXAMPLE_OUT:-results/example-check}"
PACKAGE="envs algorithms bench reports studies paper pyproject.toml constraints.txt reproduction"
before=$(git status --porcelain -- $PACKAGE; git diff -- $PACKAGE | sha256sum)

"$VENV/bin/pip" install --quiet --no-deps -e examples/external_method
"$BENCH" methods --json | grep -q "entry point (wmb-example-methods)" || { echo "example-check: entry points not listed" >&2; exit 1; }
"$BENCH" methods linear
"$VENV/bin/python" -m pytest -q -p no:cacheprovider examples/external_method/tests

rm -rf "$OUT"
"$BENCH" run --grid-file examples/external_method/smoke.toml --out "$OUT/smoke"
"$BENCH" report --run "$OUT/smoke"
PYTHONPATH=examples/module_path "$BENCH" run --grid-file examples/module_path/grid.toml --out "$OUT/module-path"
PYTHONPATH=examples/module_path "$BENCH" report --run "$OUT/module-path"
"$BENCH" run --grid-file examples/external_method/vs-paper.toml --out "$OUT/vs-paper"
"$BENCH" report --run "$OUT/vs-paper" --against reproduction/paper
"$BENCH" tune --study example-linear-lr --method linear --param lr=0.01,0.1 --replicates 1 --out "$OUT/studies"
"$BENCH" eval --method linear --n-robots 8 --layout tiny --episodes 4 --horizon 30
PYTHONPATH=examples/module_path "$BENCH" eval --method wmb_random:RandomWalk --n-robots 8 --layout tiny --episodes 4 --horizon 30

for want in "Greedy (example)|$OUT/smoke/report/leaderboard.md" "Linear (example)|$OUT/smoke/report/leaderboard.md" \
            "Random walk (example)|$OUT/module-path/report/leaderboard.md" \
            "Greedy (example)|$OUT/vs-paper/report/leaderboard.md" "Hierarchical (ours)|$OUT/vs-paper/report/leaderboard.md" \
            "merged with|$OUT/vs-paper/report/index.md" \
            "## above_baselines_greedy|$OUT/vs-paper/report/claims.md" \
            "Greedy (example) above each baseline (mean success)|$OUT/vs-paper/report/claims.md" \
            "vs PIBT, N = 20, p = 0.2|$OUT/vs-paper/report/claims.md" \
            "Greedy (example) above each baseline|$OUT/vs-paper/report/index.html" \
            "## above_baselines_wmb_random:RandomWalk|$OUT/module-path/report/claims.md"; do
  grep -q "${want%%|*}" "${want#*|}" || { echo "example-check: '${want%%|*}' missing from ${want#*|}" >&2; exit 1; }
done
# A run of outside methods only: the generic report (leaderboard first, the learning curves of
# its learned method) and no section of the paper's wing.
first=$(grep -m1 '^### ' "$OUT/smoke/report/index.md")
[ "$first" = "### Leaderboard: every method of the run" ] || { echo "example-check: the smoke report opens with '$first'" >&2; exit 1; }
grep -q "Linear (example)" "$OUT/smoke/report/learning_curves.txt" || { echo "example-check: no learning curve of linear" >&2; exit 1; }
! grep -q "The paper's reproduction" "$OUT/smoke/report/index.md" || { echo "example-check: a paper section in a run of outside methods" >&2; exit 1; }
after=$(git status --porcelain -- $PACKAGE; git diff -- $PACKAGE | sha256sum)
[ "$before" = "$after" ] || { echo "example-check: files of this package changed" >&2; exit 1; }
echo "example-check: both outside packages ran through methods, run, report (--against), tune and eval, their claims on the claims pages; this package unchanged"
