"""Methods are plugins: no module outside ``algorithms/<method>`` names a built-in method
for behaviour (SPEC 3). What a method is (learned or planner, its modes, its safety-filter
default, its payload model, its label and colour) is declared by the method and read
through the registry. The modules below name methods as data or as the paper's own
content, each for the reason given; a new mention anywhere else fails this test, and so
does an entry here that no longer mentions one (the list stays honest).
"""
from __future__ import annotations

import io
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BUILT_INS = {"hierarchical", "decentralized", "ic3net", "pibt"}
SCANNED = ("bench", "reports", "studies", "envs", "algorithms/common", "algorithms/base.py",
           "algorithms/registry.py", "algorithms/testing.py")
ALLOWED = {
    "bench/design/grids.py": "the paper's and the benchmark's grids name the methods they run (configuration data)",
    "bench/design/costs.py": "cost rates measured per method (data)",
    "bench/cli.py": "`bench perf --suite` names of benchmarks of the built-ins' own kernels",
    "bench/perf/methods.py": "benchmarks of the built-in methods' kernels",
    "bench/perf/baselines.py": "benchmarks of the built-in baselines' kernels",
    "bench/perf/cli.py": "times commands that name a built-in method (a misspelled one, PIBT's eval)",
    "bench/perf/peers.py": "benchmarks the built-in decentralized trainer against TorchRL's MAPPO",
    "reports/claims/claims.py": "the paper's own claims (Sec. IV) are about its method and baselines",
    "reports/claims/catalog.py": "the list of the paper's claims, each about its method and baselines",
    "reports/claims/calibrate.py": "simulates the paper's claims on synthetic rows of those methods",
    "reports/claims/calibrate_data.py": "resamples the paper's claims from the committed rows of those methods",
    "reports/figures/fig1_training.py": "the paper's Fig. 1 (hierarchical vs decentralized)",
    "reports/figures/fig2_success.py": "the paper's Fig. 2 (hierarchical vs IC3Net)",
    "reports/figures/fig3_payload.py": "the paper's Fig. 3 (hierarchical vs all-to-all payload)",
    "reports/data/payload.py": "the payload points of the paper's Fig. 3 and its payload claim "
                               "(hierarchical vs decentralized)",
    "reports/tables/table1_safety.py": "the paper's Table I (the hierarchical method's filter)",
    "reports/tables/ablation.py": "the ablation of the paper's method against its baseline",
    "studies/objective.py": "the paper's study (|R_z| x L of its method) is the default study",
}


def _mentions(path: Path) -> list[int]:
    """Lines of ``path`` holding a string literal that is exactly a built-in method name."""
    lines = []
    for tok in tokenize.generate_tokens(io.StringIO(path.read_text()).readline):
        if tok.type == tokenize.STRING and tok.string.strip("'\"") in BUILT_INS:
            lines.append(tok.start[0])
    return lines


def _scanned() -> list[Path]:
    out = []
    for entry in SCANNED:
        p = ROOT / entry
        out += [p] if p.suffix == ".py" else sorted(p.rglob("*.py"))
    return out


def test_no_module_outside_a_method_names_a_built_in_method_for_behaviour() -> None:
    found = {str(p.relative_to(ROOT)): _mentions(p) for p in _scanned()}
    unexpected = {f: lines for f, lines in found.items() if lines and f not in ALLOWED}
    assert not unexpected, f"built-in method names outside their modules: {unexpected}"


def test_every_allowed_module_still_names_one() -> None:
    stale = [f for f in ALLOWED if not _mentions(ROOT / f)]
    assert not stale, f"drop these from ALLOWED: {stale}"
