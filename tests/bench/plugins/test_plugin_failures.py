"""Issue 52: every failure of an outside method or logger is one line naming it, exit 2
(D13 import, D15 NaN actions, D16 non-finite payload, D20 logger factory), its prints go to
stderr (D14) and it cannot take a built-in's name or label (D23). Fast: in-process CLI, the
plugins are modules written to a temporary folder on sys.path."""
from __future__ import annotations

import json
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path

import pytest

from algorithms import registry
from tests.bench.conftest import one_error_line, run_cli, toy_spec, write_grid_file

# A planner that Waits; ``ACTIONS`` and ``PAYLOAD`` let a plugin module bend its output.
WAITER = '''
import numpy as np
from algorithms.base import Method, MethodParams
from algorithms.common.episodes import Decision

ACTIONS = None
PAYLOAD = 0.0
NOISY = False
RAISE = ""


class Waiter(Method):
    name = "waiter"
    learned = False
    Params = MethodParams

    def begin(self, batch, choice):
        return None

    def decide(self, batch, state, choice):
        if NOISY:
            print("decide was here")
        if RAISE:
            raise ValueError(RAISE)
        core = batch.core
        actions = np.full(core.pos.shape, 4, dtype=np.int64) if ACTIONS is None else np.full(core.pos.shape, ACTIONS)
        return Decision(actions=actions, payload=PAYLOAD)
'''

PLUGINS = {
    "raises_at_import": "raise RuntimeError('the plugin broke at import')\n",
    "syntax_error": "def broken(:\n    pass\n",
    "noisy": "print('imported noisy')\n" + WAITER + "NOISY = True\n",
    "raises_in_decide": WAITER + "RAISE = 'the plugin broke in decide ' + 'x' * 300\n",
    "nan_actions": WAITER + "ACTIONS = float('nan')\n",
    "nan_payload": WAITER + "PAYLOAD = float('inf')\n",
    "undeclared_nan_payload": WAITER + "PAYLOAD = float('nan')\n",
    "declared_nan_payload": WAITER + "PAYLOAD = float('nan')\nWaiter.payload_not_modelled = True\n",
    "impostor": WAITER + "Waiter.name = 'pibt'\nWaiter.display_name = 'PIBT'\n",
    "label_impostor": WAITER + "Waiter.display_name = 'pibt'\n",
}


@pytest.fixture
def plugins(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The PLUGINS modules, importable (a fresh import each test)."""
    folder = tmp_path / "plugins"
    folder.mkdir()
    for name, text in PLUGINS.items():
        (folder / f"p52_{name}.py").write_text(textwrap.dedent(text))
    monkeypatch.syspath_prepend(str(folder))
    registry.method_class.cache_clear()
    yield folder
    for name in PLUGINS:
        sys.modules.pop(f"p52_{name}", None)
    registry.method_class.cache_clear()


EVAL = ("eval", "--n-robots", "4", "--layout", "tiny", "--horizon", "6", "--episodes", "1")


@pytest.mark.parametrize("module", ["raises_at_import", "syntax_error"])
def test_d13_a_plugin_that_raises_at_import_is_one_line_and_the_others_stay_listed(
        plugins: Path, module: str, capsys: pytest.CaptureFixture[str]) -> None:
    registry.register("broken", f"p52_{module}:Waiter")
    try:
        code, out, err = run_cli(capsys, "methods", "--json")
    finally:
        registry.unregister("broken")
    assert code == 2
    one_error_line(err, "method 'broken'", f"p52_{module}:Waiter")
    listed = [m["name"] for m in json.loads(out)]
    assert "pibt" in listed and "broken" not in listed


def test_d13_a_broken_plugin_leaves_the_report_of_a_run_that_never_used_it(
        plugins: Path, one_cell_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    registry.register("broken", "p52_raises_at_import:Waiter")
    try:
        code, _, err = run_cli(capsys, "report", "--run", str(one_cell_run), "--out", str(tmp_path / "rep"))
    finally:
        registry.unregister("broken")
    assert code == 0, err
    assert (tmp_path / "rep" / "summary.json").is_file() or any((tmp_path / "rep").iterdir())


def test_d14_plugin_prints_go_to_stderr_and_json_stays_parseable(
        plugins: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run_cli(capsys, "methods", "p52_noisy:Waiter", "--json")
    assert code == 0 and json.loads(out)[0]["name"] == "p52_noisy:Waiter"
    assert "imported noisy" in err
    code, out, err = run_cli(capsys, *EVAL, "--method", "p52_noisy:Waiter", "--json")
    assert code == 0, err
    assert json.loads(out)["executions"] == ["planner"]
    assert "decide was here" in err


def test_d15_an_outside_method_that_raises_is_one_line_naming_it(
        plugins: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """An untrained outside method that raises (here a ValueError) is the method's error, cut
    to 200 characters, not a checkpoint that does not fit."""
    code, _, err = run_cli(capsys, *EVAL, "--method", "p52_raises_in_decide:Waiter")
    assert code == 2
    prefix = "bench: error: method p52_raises_in_decide:Waiter: ValueError: "
    one_error_line(err, prefix + "the plugin broke in decide xxx")
    assert len(err.strip()) == len(prefix) + 200, err


def test_d15_a_builtin_methods_bug_keeps_its_traceback(monkeypatch: pytest.MonkeyPatch) -> None:
    from algorithms.pibt import PIBTMethod
    from bench.execute.quick_eval import quick_eval

    def broken(*args: object, **kwargs: object) -> None:
        raise ZeroDivisionError("a bug of this package")

    monkeypatch.setattr(PIBTMethod, "decide", broken)
    with pytest.raises(ZeroDivisionError, match="a bug of this package"):
        quick_eval("pibt", n_robots=4, layout="tiny", horizon=6, episodes=1)


def test_d15_nan_actions_are_one_line_naming_the_method(plugins: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(capsys, *EVAL, "--method", "p52_nan_actions:Waiter")
    assert code == 2
    one_error_line(err, "method waiter", "action nan is not an integer in 0..4")


def test_d15_fractional_float_actions_are_refused_and_integral_floats_still_work() -> None:
    import numpy as np

    from envs.config import EnvConfig
    from envs.core import WarehouseCore
    from envs.errors import BenchError
    from envs.layouts import load_layout
    from envs.scenarios import sample_scenarios

    cfg = EnvConfig(n_robots=2, layout="tiny", horizon=6)
    core = WarehouseCore(cfg, load_layout("tiny"))
    starts, goals = sample_scenarios(core.layout, 2, 1, np.random.default_rng(0))
    core.reset(starts, goals)
    with pytest.raises(BenchError, match="action 2.5 is not an integer"):
        core.step(np.full((1, 2), 2.5))
    core.step(np.full((1, 2), 4.0))  # Wait as a float: accepted as before
    assert core.t == 1


@pytest.mark.parametrize("module, value", [("nan_payload", "inf"), ("undeclared_nan_payload", "nan")])
def test_d16_a_non_finite_payload_is_one_line_naming_the_method(
        plugins: Path, capsys: pytest.CaptureFixture[str], module: str, value: str) -> None:
    code, _, err = run_cli(capsys, *EVAL, "--method", f"p52_{module}:Waiter")
    assert code == 2
    one_error_line(err, "method waiter", f"Decision.payload holds {value}")


def test_d16_a_method_that_declares_its_payload_not_modelled_reports_nan(
        plugins: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run_cli(capsys, *EVAL, "--method", "p52_declared_nan_payload:Waiter", "--json")
    assert code == 0, err
    assert json.loads(out)["mean"]["planner"]["payload_scalars_per_step"] is None  # NaN: not modelled


@pytest.mark.parametrize("module, field", [("impostor", "name 'pibt'"), ("label_impostor", "display name 'pibt'")])
def test_d23_an_outside_method_cannot_take_a_builtins_name_or_label(
        plugins: Path, module: str, field: str, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(capsys, *EVAL, "--method", f"p52_{module}:Waiter")
    assert code == 2
    one_error_line(err, f"p52_{module}:Waiter", f"declares the {field}", "built-in method 'pibt'")


def test_d20_a_logger_whose_call_fails_is_one_line(toy: str, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    grid = write_grid_file(tmp_path / "g.toml", toy_spec(), {"seed": [0]})
    code, _, err = run_cli(capsys, "run", "--grid-file", str(grid), "--out", str(tmp_path / "run"),
                           "--log", "os:system")
    assert code == 2
    one_error_line(err, "--log os:system: calling it as os:system(tracking_dir, grid_name) failed (TypeError")
    assert not (tmp_path / "run").exists()


def test_d20_a_logger_factory_that_returns_no_logger_is_one_line(tmp_path: Path) -> None:
    from bench.tracking import make_observer, parse_log
    from envs.errors import BenchError

    with pytest.raises(BenchError, match=r"--log builtins:slice: .* returned slice, not a logger"):
        make_observer(parse_log("builtins:slice"), tmp_path / "run", "g")
