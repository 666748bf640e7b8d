"""`bench matrix`: every checkpoint of a tiny run (2 trained N x 2 trained p, toy method and
PIBT) on a grid of evaluation conditions. Shape, pairing of scenarios across methods and
training conditions, resume, unsupported N', bad arguments; one test on Ray, one with the
real learned methods. The run is trained in-process (conftest ``write_finished_store``)."""
from __future__ import annotations

import json
import math
import re
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest

from bench.design.cells import Cell
from bench.design.grids import Grid
from bench.execute import matrix
from bench.execute.matrix import Condition, read_matrix, run_matrix
from bench.execute.worker import CellWorker
from envs.errors import BenchError
from tests.bench.conftest import (
    cli_argv,
    snapshot,
    store_with_params,
    toy_spec,
    write_finished_store,
)

REPO = Path(__file__).resolve().parents[3]
K = 3  # evaluation episodes per condition (one chunk)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """Toy cells at N in {4, 6} x p in {0.2, 0.6}, plus PIBT at the same four conditions."""
    from algorithms import registry
    from tests.bench.toy_method import TOY_PATH

    registry.register("toy", TOY_PATH)
    cells = [Cell.make(**toy_spec(n_robots=n, loss_p=p, episodes=4, eval_episodes=2, seed=int(p == 0.6)))
             for n in (4, 6) for p in (0.2, 0.6)]  # seeds differ: pairing must not come from the cell
    cells += [Cell.make(method="pibt", n_robots=n, loss_p=p, layout="tiny", episodes=0, horizon=12, eval_episodes=2)
              for n in (4, 6) for p in (0.2, 0.6)]
    out = tmp_path_factory.mktemp("matrix") / "run"
    write_finished_store(out, Grid("toygrid", "test", tuple(cells)))
    yield out
    registry.unregister("toy")


def _frame(run: Path) -> pd.DataFrame:
    table = read_matrix(run)
    assert table is not None
    return table.to_pandas()


def test_matrix__shape_columns_and_pairing(toy: str, tiny_run: Path, tmp_path: Path) -> None:
    import shutil

    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    s = run_matrix(run, ps=[0.0, 0.5], bursts=[4.0], episodes=K, use_ray=False)
    # conditions: N' in {4, 6} x (p'=0: Bernoulli; p'=0.5: Bernoulli, GE b=4) = 6; 8 cells
    assert (s.units, s.written, s.skipped, s.unsupported, s.failed) == (48, 48, 0, 0, {})
    df = _frame(run)
    toy_rows = df[df.method == "toy"]
    pibt_rows = df[df.method == "pibt"]
    assert len(toy_rows) == 4 * 6 * K * 3 and len(pibt_rows) == 4 * 6 * K
    assert sorted(toy_rows.execution.unique()) == ["argmax", "sample", "sample@0.5"]
    assert set(pibt_rows.execution) == {"planner"}
    assert (df.status == "ok").all() and set(df.episode) == set(range(K))
    assert set(df.condition) == {"n4-p0-bernoulli", "n4-p0.5-bernoulli", "n4-p0.5-ge-b4",
                                 "n6-p0-bernoulli", "n6-p0.5-bernoulli", "n6-p0.5-ge-b4"}
    ge = df[df.loss_model == "gilbert_elliott"]
    assert (ge.burst_length == 4.0).all() and df[df.loss_model == "bernoulli"].burst_length.isna().all()
    assert {(r.train_n, r.train_p) for r in df.itertuples()} == {(4, 0.2), (4, 0.6), (6, 0.2), (6, 0.6)}
    # paired: one scenario per (N', episode) across methods, training conditions, seeds, p',
    # loss models and modes; different N' or episodes see different scenarios
    per = df.groupby(["eval_n", "episode"])["scenario"].nunique()
    assert (per == 1).all()
    assert df["scenario"].nunique() == 2 * K
    # PIBT ignores the channel: on paired scenarios its rows are equal at every p', loss model
    # and training condition of an N' (common random numbers make this exact)
    cols = ["success_rate", "collision_rate", "steps"]
    assert (pibt_rows.groupby(["eval_n", "episode"])[cols].nunique() == 1).all().all()
    assert set(df.eval_seed) == {Condition(4, 0.0, "bernoulli", math.nan, "tiny").seed,
                                 Condition(6, 0.0, "bernoulli", math.nan, "tiny").seed}
    # at the training condition with the cell's own chunking the rows would match eval/ only by
    # chance; at p'=0 every toy argmax policy runs without loss: metrics are finite
    assert toy_rows.success_rate.between(0, 1).all()


def test_matrix__pairing_does_not_depend_on_the_cell_seed(toy: str, tiny_run: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """The planted bug 'seed from the cell' would give every cell its own scenarios: two
    cells differing only in seed must see the same ones."""
    spec0 = matrix.Unit(Cell.make(**toy_spec(seed=0)), Condition(4, 0.2, "bernoulli", math.nan, "tiny"), ("argmax",), K)
    spec1 = matrix.Unit(Cell.make(**toy_spec(seed=5)), spec0.cond, ("argmax",), K)
    matrix._prepare(spec0)
    matrix._prepare(spec1)
    assert spec0.spec["seed"] == spec1.spec["seed"] == spec0.cond.seed
    assert spec0.spec["params"]["eval_chunk"] == matrix.MATRIX_CHUNK


def test_matrix__rerun_skips_done_units_and_redoes_a_missing_one(toy: str, tiny_run: Path, tmp_path: Path) -> None:
    import shutil

    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    first = run_matrix(run, ns=[4], ps=[0.2], models=["bernoulli"], episodes=K, use_ray=False)
    assert (first.written, first.skipped) == (8, 0)
    before = snapshot(run / "matrix")
    seen: list[str] = []
    again = run_matrix(run, ns=[4], ps=[0.2], models=["bernoulli"], episodes=K, use_ray=False,
                       on_unit=lambda u: seen.append(u.cell.cell_id))
    assert (again.written, again.skipped, seen) == (0, 8, [])
    assert snapshot(run / "matrix") == before
    victim = sorted((run / "matrix").glob("*/*.parquet"))[0]
    victim.unlink()
    third = run_matrix(run, ns=[4], ps=[0.2], models=["bernoulli"], episodes=K, use_ray=False)
    assert (third.written, third.skipped) == (1, 7)
    assert snapshot(run / "matrix") == before  # recomputed bit for bit
    # another K is another matrix: every unit is redone
    assert run_matrix(run, ns=[4], ps=[0.2], models=["bernoulli"], episodes=K + 1, use_ray=False).written == 8


def test_matrix__n_below_the_groups_is_an_unsupported_row(toy: str, tiny_run: Path, tmp_path: Path) -> None:
    import shutil

    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    s = run_matrix(run, ns=[3], ps=[0.2], models=["bernoulli"], episodes=K, use_ray=False)
    assert (s.written, s.unsupported) == (0, 8)
    df = _frame(run)
    assert len(df) == 8 and (df.status == "unsupported").all() and (df.episode == -1).all()
    assert df.reason.str.contains("N'=3 < Z=4").all()
    again = run_matrix(run, ns=[3], ps=[0.2], models=["bernoulli"], episodes=K, use_ray=False)
    assert (again.skipped, again.unsupported) == (8, 0)


@pytest.mark.parametrize("kwargs, message", [
    (dict(ps=[1.2]), "--p 1.2: a loss probability must be in [0, 1]"),
    (dict(ps=[-0.1]), "--p -0.1"),
    (dict(ns=[0]), "--n 0: a team needs at least 1 robot"),
    (dict(ns=[500]), "--n 500: 500 robots do not fit layout 'tiny'"),
    (dict(models=["burst"]), "--loss-model 'burst': unknown loss model"),
    (dict(bursts=[0.5]), "--burst 0.5"),
    (dict(ps=[0.9], bursts=[4.0]), "--p 0.9 with --burst 4: mean loss 0.9 is more than bursts of 4 steps allow"),
    (dict(episodes=0), "--episodes 0"),
    (dict(delays=[-1.0]), "--delay -1: a mean message delay must be a finite number of steps >= 0"),
    (dict(delays=[math.nan]), "--delay nan: a mean message delay must be a finite number"),
    (dict(delays=[1.5]), "--delay 1.5 with --delay-model fixed: a fixed delay is a whole number of steps "
                         "(or use --delay-model geometric)"),
    (dict(delays=[20.0]), "--delay 20 with --delay-model fixed: delay=20 exceeds delay_max=16"),
    (dict(delays=[16.0], delay_models=["geometric"]),
     "--delay 16 with --delay-model geometric: a geometric mean delay must be below delay_max=16"),
    (dict(delay_models=["late"]), "--delay-model 'late': unknown delay model; choose fixed or geometric"),
])
def test_matrix__bad_arguments_are_one_bench_error(toy: str, tiny_run: Path, kwargs: dict, message: str) -> None:
    before = snapshot(tiny_run)
    with pytest.raises(BenchError, match=re.escape(message)):
        run_matrix(tiny_run, use_ray=False, **kwargs)
    assert snapshot(tiny_run) == before


def test_matrix__a_run_without_checkpoints_is_refused(toy: str, tiny_run: Path, tmp_path: Path) -> None:
    import shutil

    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    shutil.rmtree(run / "checkpoints")
    with pytest.raises(BenchError, match="has no trained checkpoints"):
        run_matrix(run, use_ray=False)
    with pytest.raises(BenchError, match="not a bench run directory"):
        run_matrix(tmp_path / "nowhere", use_ray=False)


def test_matrix__cells_trained_under_other_defaults_are_refused(toy: str, tiny_run: Path, tmp_path: Path) -> None:
    import shutil

    from bench.store.run_store import RunStore

    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    cells = RunStore(run).read_cells()
    store_with_params(run, str(cells.loc[cells["method"] == "toy", "cell_id"].iloc[0]), lr=0.5)
    before = snapshot(run)
    with pytest.raises(BenchError, match=r"1 done cell\(s\) .* lr: 0.5 -> 0.05; run `bench run --rerun-changed`"):
        run_matrix(run, use_ray=False)
    assert snapshot(run) == before


@pytest.mark.parametrize("args, line", [
    (("--p", "1.5"), "--p 1.5: a loss probability must be in [0, 1]"),
    (("--delay", "2.5"), "--delay 2.5 with --delay-model fixed: a fixed delay is a whole number of steps "
                         "(or use --delay-model geometric)"),
    (("--delay=-2",), "--delay -2: a mean message delay must be a finite number of steps >= 0"),
])
def test_cli__bad_p_or_delay_is_one_line_and_exit_2(tiny_run: Path, args: tuple[str, ...], line: str) -> None:
    proc = subprocess.run(cli_argv("matrix", "--run", str(tiny_run), *args), cwd=REPO,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [f"bench: error: {line}"]


def test_matrix__ray_gives_the_rows_of_the_in_process_evaluation(toy: str, tiny_run: Path, tmp_path: Path,
                                                                  ray_local: None) -> None:
    import shutil

    local, remote = tmp_path / "local", tmp_path / "remote"
    shutil.copytree(tiny_run, local)
    shutil.copytree(tiny_run, remote)
    args = dict(ns=[4], ps=[0.4], bursts=[16.0], episodes=12)  # two chunks per mode
    run_matrix(local, use_ray=False, **args)
    s = run_matrix(remote, workers=2, **args)
    assert (s.written, s.failed) == (16, {})
    key = ["cell_id", "condition", "execution", "episode"]
    a = _frame(local).sort_values(key).reset_index(drop=True)
    b = _frame(remote).sort_values(key).reset_index(drop=True)
    pd.testing.assert_frame_equal(a, b)
    assert sorted(a.episode.unique()) == list(range(12))
    assert run_matrix(remote, workers=2, **args).skipped == 16


def test_matrix__a_worker_that_dies_is_retried_on_ray(toy: str, tiny_run: Path, tmp_path: Path, ray_local: None,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    import shutil

    from bench.execute import executor

    for actors in executor._IDLE.values():  # plain workers of an earlier test: not reused here
        executor._kill(actors)
    executor._IDLE.clear()
    local, remote = tmp_path / "local", tmp_path / "remote"
    shutil.copytree(tiny_run, local)
    shutil.copytree(tiny_run, remote)
    marker = str(tmp_path / "died")

    class DyingWorker(CellWorker):
        """SIGKILLs its own process on its first evaluation chunk (once: marker file); a local
        class, so Ray ships it by value with the marker path."""

        def eval_chunk(self, spec, state_box, chunk, execution=None):  # type: ignore[no-untyped-def]
            import os
            import signal

            from tests.crash_once import first_claim

            if first_claim(marker):
                os.kill(os.getpid(), signal.SIGKILL)
            return super().eval_chunk(spec, state_box, chunk, execution)

    monkeypatch.setattr(matrix, "CellWorker", DyingWorker)
    args = dict(ns=[4], ps=[0.4], models=["bernoulli"], episodes=K)
    s = run_matrix(remote, workers=2, **args)
    assert Path(marker).exists() and (s.written, s.failed) == (8, {})
    for actors in executor._IDLE.values():
        executor._kill(actors)
    executor._IDLE.clear()
    monkeypatch.setattr(matrix, "CellWorker", CellWorker)
    run_matrix(local, use_ray=False, **args)
    key = ["cell_id", "condition", "execution", "episode"]
    pd.testing.assert_frame_equal(_frame(local).sort_values(key).reset_index(drop=True),
                                  _frame(remote).sort_values(key).reset_index(drop=True))


def test_matrix__real_methods_at_another_team_size(tmp_path: Path) -> None:
    """Hierarchical (Z = 2 groups) and decentralized checkpoints trained at N = 4 run at
    N' = 6 (Z kept, uneven groups padded) and are 'unsupported' for the hierarchical at N' < Z."""
    base = dict(loss_p=0.2, layout="tiny", episodes=2, horizon=8, eval_episodes=2, groups=2,
                params={"batch_episodes": 2, "eval_chunk": 2, "hidden": 8, "critic_hidden": 8})
    cells = [Cell.make(method=m, n_robots=4, **base) for m in ("hierarchical", "decentralized")]
    run = tmp_path / "run"
    write_finished_store(run, Grid("real", "test", tuple(cells)))
    s = run_matrix(run, ns=[1, 6], ps=[0.5], models=["bernoulli"], episodes=2, use_ray=False)
    assert (s.written, s.unsupported, s.failed) == (2, 2, {})
    df = _frame(run)
    ok = df[df.status == "ok"]
    assert set(ok.eval_n) == {6} and set(ok.method) == {"hierarchical", "decentralized"}
    assert (ok.groupby(["condition", "episode"])["scenario"].nunique() == 1).all()
    bad = df[df.status == "unsupported"]
    assert set(bad.eval_n) == {1} and bad.reason.str.contains("N'=1 < Z=2").all()


def _synthetic(success: dict[tuple[str, int, float], list[float]]) -> pd.DataFrame:
    """Matrix rows: (method, seed, eval_p) -> success of each episode (N = N' = 4, trained p = 0.2)."""
    rows = []
    for (method, seed, p), values in success.items():
        for k, v in enumerate(values):
            rows.append(dict(cell_id=f"{method}{seed}", method=method, seed=seed, train_n=4, train_p=0.2,
                             eval_n=4, eval_p=p, loss_model="bernoulli", burst_length=math.nan,
                             status="ok", reason="", episode=k, execution="argmax", success_rate=v))
    return pd.DataFrame(rows)


def test_report__interval_is_over_seed_means_and_the_sentence_quotes_the_kept_share() -> None:
    from reports.matrix import matrix_table, summary_sentences
    from reports.stats import rate_ci

    # seed means at p'=0.2: 0.8, 0.6, 1.0; at p'=0.8: 0.4, 0.3, 0.5 -> kept 50% in every seed
    data = {("hierarchical", 0, 0.2): [0.8, 0.8], ("hierarchical", 1, 0.2): [0.4, 0.8],
            ("hierarchical", 2, 0.2): [1.0, 1.0], ("hierarchical", 0, 0.8): [0.4, 0.4],
            ("hierarchical", 1, 0.8): [0.2, 0.4], ("hierarchical", 2, 0.8): [0.5, 0.5],
            ("decentralized", 0, 0.2): [1.0, 1.0], ("decentralized", 0, 0.8): [0.25, 0.25]}
    df = _synthetic(data)
    t = matrix_table(df).set_index(["method", "eval_p"])
    m, lo, hi = rate_ci([0.8, 0.6, 1.0])
    row = t.loc[("hierarchical", 0.2)]
    assert 0.0 <= lo < m < hi <= 1.0  # a success rate's interval stays inside [0, 1] by construction
    assert (row.success, row.lo, row.hi, row.seeds) == pytest.approx((m, lo, hi, 3))
    assert math.isnan(t.loc[("decentralized", 0.2)].lo)  # one seed: no interval
    (sentence,) = summary_sentences(df)
    assert sentence.startswith("Trained at N=4, p=0.2 and evaluated at p'=0.8 (Bernoulli, N'=4): ")
    assert "Hierarchical (ours) keeps 50% (95% CI 50-50%) of its success (0.80 -> 0.40, 3 seeds)" in sentence
    assert "Decentralized keeps 25% of its success (1.00 -> 0.25, 1 seed)" in sentence


def test_report__matrix_section_from_a_tiny_run(toy: str, tiny_run: Path, tmp_path: Path) -> None:
    import shutil

    from reports.build import build_report

    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    run_matrix(run, ns=[3, 4, 6], ps=[0.2, 0.6], bursts=[4.0], episodes=2, use_ray=False)
    out = build_report(run)
    for name in ("matrix_heatmaps.png", "matrix_degradation.pdf", "matrix_bursty.png", "matrix.md", "matrix.csv"):
        assert (out / name).stat().st_size > 0
    md = (out / "matrix.md").read_text()
    assert "Trained at N=4, p=0.2 and evaluated at p'=0.6" in md and "## Units that cannot run" in md
    assert "N'=3 < Z=4" in md
    assert "Robustness matrix" in (out / "index.md").read_text()
    csv = pd.read_csv(out / "matrix.csv")
    assert set(csv.execution) == {"argmax", "sample", "sample@0.5", "planner"}
    victim = sorted((run / "matrix").glob("*/*.parquet"))[0]
    victim.write_bytes(b"not parquet")  # a corrupt unit is named, the rest is reported
    build_report(run)
    assert f"skipped {victim.relative_to(run).as_posix()}: damaged file" in (out / "index.md").read_text()
    with pytest.raises(BenchError, match="corrupt Parquet file"):
        read_matrix(run)


def test_matrix__a_failing_unit_is_not_written_and_a_rerun_retries_it(toy: str, tiny_run: Path, tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    import shutil

    from tests.bench.toy_method import ToyMethod

    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    original = ToyMethod.evaluate

    def broken(self: ToyMethod, chunk: int, seed: int | None = None, execution: str | None = None) -> list:
        if self.env.n_robots == 6:
            raise RuntimeError("toy cannot evaluate at N'=6")
        return original(self, chunk, seed, execution)

    monkeypatch.setattr(ToyMethod, "evaluate", broken)
    s = run_matrix(run, ps=[0.2], models=["bernoulli"], episodes=K, use_ray=False)
    # 8 cells x N' in {4, 6}: the 4 toy cells fail at N'=6, the other 12 units are written
    assert (s.units, s.written, len(s.failed)) == (16, 12, 4)
    assert all("RuntimeError: toy cannot evaluate at N'=6" in e for e in s.failed.values())
    failed_files = {run / "matrix" / f"{key}.parquet" for key in s.failed}
    assert len(failed_files) == 4 and not any(p.exists() for p in failed_files)
    monkeypatch.setattr(ToyMethod, "evaluate", original)
    again = run_matrix(run, ps=[0.2], models=["bernoulli"], episodes=K, use_ray=False)
    assert (again.written, again.skipped, again.failed) == (4, 12, {})
    assert all(p.exists() for p in failed_files)


def test_matrix__a_flipped_bit_or_a_misplaced_unit_is_named_and_repair_redoes_only_it(
        toy: str, tiny_run: Path, tmp_path: Path) -> None:
    """Issue 37 (D2/D3 for matrix files): a damaged unit file is refused naming it and
    `bench matrix --repair`; with repair it moves to superseded/ and only it is evaluated."""
    import shutil

    from bench.store.run_store import RunStore
    from envs.errors import BenchError

    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    store = RunStore(run)  # a run of this bench: checksums in force, so matrix records its files
    store.write_manifest({**store.read_manifest(), "runs": [{"grid": "toygrid", "checksums": 1}]})
    store.integrity().start_recording()
    args = dict(ns=[4], ps=[0.2], models=["bernoulli"], episodes=K, use_ray=False)
    run_matrix(run, **args)
    recorded = json.loads((run / "checksums.json").read_text())["files"]
    assert sum(k.startswith("matrix/") for k in recorded) == 8
    before = snapshot(run / "matrix")
    units = sorted((run / "matrix").glob("*/*.parquet"))
    victim, other = units[0], units[-1]
    data = bytearray(victim.read_bytes())
    data[len(data) // 2] ^= 0x08
    victim.write_bytes(bytes(data))
    with pytest.raises(BenchError,
        match=rf"damaged file matrix/{victim.parent.name}/{victim.name}: .*bench matrix.*--repair"):
        run_matrix(run, **args)
    s = run_matrix(run, repair=True, **args)
    assert (s.written, s.skipped) == (1, 7)
    assert snapshot(run / "matrix") == before
    shutil.copyfile(other, run / "matrix" / victim.parent.name / other.name)  # another cell's unit
    with pytest.raises(BenchError, match="holds rows of cell"):
        run_matrix(run, **args)


@pytest.fixture(scope="module")
def delay_run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """Age-probe cells (tests/bench/toy_method.py ``AgeProbe``: its predictor_error column is
    the mean age of the messages it holds) trained with lifelong tasks at delay 0 and at a
    fixed delay 2, two seeds each, plus PIBT."""
    from algorithms import registry
    from tests.bench.toy_method import AGE_PROBE_PATH

    registry.register("ageprobe", AGE_PROBE_PATH)
    cells = [Cell.make(**toy_spec(method="ageprobe", task="lifelong", delay=d, seed=s, episodes=2, eval_episodes=2))
             for d in (0.0, 2.0) for s in (0, 1)]
    cells += [Cell.make(method="pibt", n_robots=4, loss_p=0.2, layout="tiny", episodes=0, horizon=12,
                        eval_episodes=2, task="lifelong")]
    out = tmp_path_factory.mktemp("delay") / "run"
    write_finished_store(out, Grid("delaygrid", "test", tuple(cells)))
    yield out
    registry.unregister("ageprobe")


@pytest.fixture
def ageprobe() -> Iterator[str]:
    from algorithms import registry
    from tests.bench.toy_method import AGE_PROBE_PATH

    registry.register("ageprobe", AGE_PROBE_PATH)
    yield "ageprobe"
    registry.unregister("ageprobe")


def test_matrix__delay_axis_evaluates_at_the_asked_delay(ageprobe: str, delay_run: Path, tmp_path: Path) -> None:
    """Trained at delay 0 and 2, evaluated at d' in {0, 1, 3} (fixed) without loss: every
    probe row's held messages are exactly d' steps old, whatever delay the cell trained at,
    and a geometric d' = 2 gives other ages; scenarios stay paired across delays."""
    import shutil

    run = tmp_path / "run"
    shutil.copytree(delay_run, run)
    s = run_matrix(run, ps=[0.0], models=["bernoulli"], delays=[0, 1, 3], episodes=K, use_ray=False)
    assert (s.units, s.written, s.failed) == (5 * 3, 15, {})
    df = _frame(run)
    assert set(df.condition) == {"n4-p0-bernoulli", "n4-p0-bernoulli-d1", "n4-p0-bernoulli-d3"}
    probe = df[df.method == "ageprobe"]
    assert {(r.train_delay, r.eval_delay) for r in probe.itertuples()} == {
        (t, e) for t in (0.0, 2.0) for e in (0.0, 1.0, 3.0)}
    assert (probe.predictor_error == probe.eval_delay).all()  # the channel the cell really ran on
    assert (df.delay_model == "fixed").all() and (df.train_delay_model == "fixed").all()
    assert (df.groupby("episode")["scenario"].nunique() == 1).all()  # paired across delays and cells
    assert df.throughput.notna().all() and (df.throughput >= 0).all()  # lifelong: the MAPF metric is kept
    pibt = df[df.method == "pibt"]  # PIBT ignores the channel: the same rows at every delay
    assert (pibt.groupby("episode")[["throughput", "steps"]].nunique() == 1).all().all()
    geo = run_matrix(run, ps=[0.0], models=["bernoulli"], delays=[2], delay_models=["geometric"], episodes=K,
                     use_ray=False)
    assert geo.written == 5
    g = _frame(run)
    g = g[(g.condition == "n4-p0-bernoulli-d2-geometric") & (g.method == "ageprobe")]
    assert len(g) == 4 * K * 3 and (g.delay_model == "geometric").all()
    assert (g.predictor_error > 0).all() and (g.predictor_error != 2.0).any()


def test_matrix__default_delays_are_the_run_s(ageprobe: str, delay_run: Path, tmp_path: Path) -> None:
    """No --delay: the delays the run's cells trained at (0 and 2), so a delay-0 run's
    matrix keeps its conditions and file names."""
    import shutil

    run = tmp_path / "run"
    shutil.copytree(delay_run, run)
    _, conds, _, _ = matrix.plan_units(run, ps=[0.0], models=["bernoulli"], episodes=K)
    assert [c.key for c in conds] == ["n4-p0-bernoulli", "n4-p0-bernoulli-d2"]
    _, conds, _, _ = matrix.plan_units(run, ps=[0.0], models=["bernoulli"], delay_models=["geometric"], episodes=K)
    assert [(c.delay, c.delay_model) for c in conds] == [(0.0, "fixed"), (2.0, "geometric")]
    assert matrix.delay_settings([0, 2, 0], ["fixed", "geometric"]) == [(0.0, "fixed"), (2.0, "fixed"),
                                                                         (2.0, "geometric")]


def test_matrix__a_file_written_before_the_delay_axis_reads_as_delay_0(toy: str, tiny_run: Path,
                                                                     tmp_path: Path) -> None:
    import shutil

    import pyarrow.parquet as pq

    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    run_matrix(run, ns=[4], ps=[0.2], models=["bernoulli"], episodes=K, use_ray=False)
    path = sorted((run / "matrix").glob("*/*.parquet"))[0]
    old = pq.read_table(path)
    old = old.drop_columns(list(matrix.ADDED_MATRIX_COLUMNS))
    pq.write_table(old, path)
    df = _frame(run)
    mine = df[df.cell_id == path.parent.name]
    assert (mine.eval_delay == 0).all() and (mine.delay_model == "fixed").all() and mine.throughput.isna().all()


def test_report__delay_matrix_section(ageprobe: str, delay_run: Path, tmp_path: Path) -> None:
    """A lifelong matrix over delay: scored by throughput, a score(d') figure, d and d' in
    the table, a sentence per trained delay; the loss figures hold d' = d."""
    import shutil

    from reports.build import build_report
    from reports.matrix import THROUGHPUT, degradation, matrix_table, own_delay, score_of

    run = tmp_path / "run"
    shutil.copytree(delay_run, run)
    run_matrix(run, ps=[0.2, 0.5], models=["bernoulli"], delays=[0, 2, 3], episodes=2, use_ray=False)
    df = _frame(run)
    assert score_of(df) is THROUGHPUT
    out = build_report(run)
    for name in ("matrix_delay.png", "matrix_delay.pdf", "matrix_heatmaps.png", "matrix.md", "matrix.csv"):
        assert (out / name).stat().st_size > 0
    md = (out / "matrix.md").read_text()
    assert "| method | N | p | d | N' | p' | loss | d' | mode | throughput | 95% CI | seeds |" in md
    assert "Trained at N=4, p=0.2, d=2 and evaluated at a fixed delay d'=3 (p'=0.2, Bernoulli, N'=4): " in md
    assert "Trained at N=4, p=0.2, d=0 and evaluated at p'=0.5 (Bernoulli, N'=4, same delay): " in md
    assert "of its throughput" in md
    assert "Robustness matrix: throughput(d') per trained delay" in (out / "index.md").read_text()
    csv = pd.read_csv(out / "matrix.csv")
    crossed = {(t, e) for t in (0.0, 2.0) for e in (0.0, 2.0, 3.0)}
    assert set(zip(csv.train_delay, csv.eval_delay, strict=True)) == crossed
    table = matrix_table(df)
    mine = own_delay(table)
    assert len(mine) and (mine.eval_delay == mine.train_delay).all() and len(mine) < len(table)
    degradation(table, THROUGHPUT)  # draws from the d' = d slice only (no error on mixed delays)
