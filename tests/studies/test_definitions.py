"""The published tuning protocol as committed definition files: one protocol for the three
learned methods, the spaces the tuning protocol lists, tuning seeds disjoint from every published grid's,
cost estimates, and one tiny study of the real hierarchical method run end to end."""
from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
import pytest

from bench.cli import main
from bench.design.costs import rate
from envs.errors import BenchError
from studies.cli import tune_study
from studies.definitions import DEFINITIONS, estimate, load_definition
from studies.schedule import replicate_seed
from studies.seeds import check_tuning_seeds, published_seeds, tuning_seeds

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

LEARNED = ("hierarchical", "decentralized", "ic3net")
# what the tuning protocol asks each study to cover (the policy's learning rate under the standard
# protocol is ppo_lr; lr acts only under the paper's)
COVERS = {"hierarchical": {"ref_size", "search_radius", "c_max", "share_params", "fallback",
                           "resample_on_fallback", "ppo_lr", "entropy_coef"},
          "decentralized": {"ppo_lr", "entropy_coef", "hidden"},
          "ic3net": {"ppo_lr", "entropy_coef", "hidden", "comm_passes"}}


def _bench(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as exc:
        main(args)
    out = capsys.readouterr()
    return int(exc.value.code or 0), out.out, out.err


@pytest.mark.parametrize("method", LEARNED)
def test_committed_definitions_share_one_protocol_and_cover_the_issues_space(method: str) -> None:
    d = load_definition(DEFINITIONS / f"{method}.toml")
    assert d.protocol_path == (DEFINITIONS / "protocol.toml").resolve()
    assert d.options["method"] == method and d.name == f"tuned-{method}"
    assert COVERS[method] <= set(d.space())
    assert d.options["params"]["protocol"] == "mappo" and "lr" not in d.space()  # the standard protocol
    assert d.trials == load_definition(DEFINITIONS / "hierarchical.toml").trials
    # beyond Lemma 1's bound for 10 robots per group at L = 2 (761 candidates)
    if method == "hierarchical":
        assert max(int(v) for v in d.space()["c_max"]) > 761
        assert set(d.space()["fallback"]) == {"joint", "per_robot"}


def test_committed_studies_use_seeds_no_published_grid_evaluates() -> None:
    published = published_seeds()
    assert {0, 1, 2} <= set(published)  # the committed reproduction's seeds are found
    for method in LEARNED:
        d = load_definition(DEFINITIONS / f"{method}.toml")
        check_tuning_seeds(d.options["seed"], d.options["replicates"], published)


def _fake_reproduction(root: Path, seed: int) -> Path:
    store = root / "reproduction" / "somegrid"
    store.mkdir(parents=True)
    pd.DataFrame({"cell_id": ["a", "b"], "seed": [0, seed]}).to_parquet(store / "cells.parquet")
    return root / "reproduction"


def test_a_study_refuses_seeds_a_committed_store_evaluates(tmp_path: Path) -> None:
    published = _fake_reproduction(tmp_path, replicate_seed(5, 1))
    with pytest.raises(BenchError, match=r"training seed of replicate 1 .* reproduction/somegrid evaluates"):
        tune_study("s", 1, {"method": "fake_hier", "seed": 5, "replicates": 2}, root=tmp_path / "studies",
                   inline=True, published=published)
    assert not (tmp_path / "studies").exists()  # refused before anything is written
    # one replicate only: its seed is not published, so the check passes that far
    check_tuning_seeds(5, 1, published_seeds(published))


def test_a_study_refuses_seeds_a_committed_grid_file_evaluates(tmp_path: Path) -> None:
    root = tmp_path / "reproduction"
    root.mkdir()
    seed = tuning_seeds(3, 1)["evaluation seed"]
    (root / "g.toml").write_text(f'[base]\nmethod = "pibt"\nn_robots = 4\nloss_p = 0.2\nlayout = "tiny"\n'
                                 f'seed = {seed}\n')
    with pytest.raises(BenchError, match=f"evaluation seed \\({seed}\\) .* reproduction/g.toml"):
        check_tuning_seeds(3, 1, published_seeds(root))


def test_estimate_is_trials_times_training_and_evaluation_agent_steps() -> None:
    d = load_definition(DEFINITIONS / "hierarchical.toml")
    e = estimate(d)
    s = e["settings"]
    assert e["train_s"] == pytest.approx(s.episodes * s.horizon * s.n_robots / rate(s.method, "train", s.n_robots))
    checks = s.iterations // s.eval_every - 1
    evals = (checks * s.report_chunks * s.eval_chunk + s.eval_episodes) * s.horizon * s.n_robots
    assert e["eval_s"] == pytest.approx(evals / rate(s.method, "eval", s.n_robots))
    assert e["worker_hours"] == pytest.approx(d.trials * (e["train_s"] + e["eval_s"]) / 3600)


def test_bench_tune_estimate_prints_worker_hours(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = _bench(["tune", "--definition", str(DEFINITIONS / "ic3net.toml"), "--estimate"], capsys)
    assert code == 0, err
    assert out.startswith("study tuned-ic3net: ic3net, 72 trials of 480 episodes") and "worker-hours" in out


def _tiny(tmp_path: Path, space: str = "ref_size = [2, 4]\nsearch_radius = [1]") -> Path:
    (tmp_path / "proto.toml").write_text(
        'n_robots = 4\nloss_p = 0.2\nlayout = "tiny"\ngroups = 2\nepisodes = 4\nhorizon = 12\n'
        'eval_every = 1\neval_episodes = 10\ntrials = 2\nreplicates = 1\nsearch = "grid"\n'
        'pruner = "none"\nseed = 47\n')
    (tmp_path / "tiny.toml").write_text(f'study = "tiny-hier"\nmethod = "hierarchical"\nprotocol = "proto.toml"\n'
                                        f'[params]\nbatch_episodes = 2\n[space]\n{space}\n')
    return tmp_path / "tiny.toml"


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_tiny_hierarchical_study_runs_end_to_end_from_its_definition(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = tmp_path / "studies"
    code, out, err = _bench(["tune", "--definition", str(_tiny(tmp_path)), "--inline", "--out", str(out_dir)], capsys)
    assert code == 0, err
    assert "study tiny-hier: 2/2 finished trials (2 complete" in out
    trials = pd.read_parquet(out_dir / "tiny-hier" / "trials.parquet")
    assert sorted(trials["ref_size"].tolist()) == [2, 4]
    assert (out_dir / "tiny-hier" / "report" / "study.md").exists()
    code, out, err = _bench(["tune", "--best", "tiny-hier", "--out", str(out_dir)], capsys)
    assert code == 0, err
    assert tomllib.loads(out)["base"]["method"] == "hierarchical"


@pytest.mark.parametrize(("args", "message"), [
    (["--estimate"], "--estimate needs --definition FILE"),
    (["--definition", "DEF", "--n-robots", "3"], "fixes the study, its protocol and its space; drop --n-robots"),
    (["--definition", "DEF", "--study", "x"], "drop --study"),
    (["--definition", "nowhere.toml"], "study definition 'nowhere.toml': cannot read"),
])
def test_definition_mistakes_are_one_line_and_exit_2(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str) -> None:
    path = str(_tiny(tmp_path))
    code, _out, err = _bench(["tune", *[path if a == "DEF" else a for a in args]], capsys)
    assert code == 2 and err.count("\n") == 1 and message in err, err


def test_a_bad_space_or_key_names_the_file(tmp_path: Path) -> None:
    with pytest.raises(BenchError, match="no_such"):
        from studies.cli import _config

        _config(load_definition(_tiny(tmp_path, "no_such = [1, 2]")).options)
    (tmp_path / "x.toml").write_text('study = "x"\nmethod = "ic3net"\nprotocol = "proto.toml"\nbudget = 3\n'
                                     '[space]\nlr = [0.1]\n')
    with pytest.raises(BenchError, match="x.toml.*unknown key 'budget'"):
        load_definition(tmp_path / "x.toml")
