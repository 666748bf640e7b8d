"""Committed study definitions: the published tuning protocol as files ``bench tune`` runs.

A definition (``studies/definitions/<method>.toml``) names the study, the method, the fixed
parameters and the search space, and points at one *protocol* file
(``studies/definitions/protocol.toml``) that holds everything the tuning protocol fixes
for every method alike (docs/studies.md, "The published tuning protocol"): the validation
configuration, the budget of a trial, the trials and replicates, the search, the pruning
rule and the study seed. Because the three learned methods' definitions share that one
file, their studies cannot differ in any of it. ``bench tune --definition FILE`` runs it
(``--estimate``: only its cost, the way ``bench grids`` prices a grid).

Definition keys: ``study`` (name), ``method``, ``protocol`` (path, relative to the
definition), ``[params]`` (fixed hyperparameters, e.g. the training protocol) and
``[space]`` (NAME = [values], as ``--param NAME=V1,V2``). Protocol keys: ``PROTOCOL_KEYS``.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from envs.errors import BenchError

__all__ = ["DEFINITIONS", "PROTOCOL_KEYS", "StudyDefinition", "estimate", "load_definition"]

DEFINITIONS = Path(__file__).resolve().parent / "definitions"
DEFINITION_KEYS = {"study", "method", "protocol", "params", "space", "description"}
# TrialSettings fields and study options the protocol fixes for every method
PROTOCOL_KEYS = {"n_robots", "loss_p", "layout", "groups", "episodes", "horizon", "eval_episodes", "eval_every",
                 "trials", "replicates", "search", "pruner", "prune_warmup", "prune_min_rho", "seed",
                 "description"}


@dataclass(frozen=True)
class StudyDefinition:
    """One committed study: its name, the options ``tune_study`` takes, and its trial count."""

    name: str
    path: Path
    protocol_path: Path
    options: dict[str, Any]  # tune_study options (method, settings, param texts, search ...)
    trials: int

    def space(self) -> dict[str, list[str]]:
        """NAME -> value strings, as ``--param`` gives them."""
        from studies.space import split_overrides

        return split_overrides(self.options["param"])


def _value_text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def _read(path: Path, what: str) -> dict[str, Any]:
    try:
        import tomllib
    except ImportError:  # pragma: no cover - Python 3.10
        import tomli as tomllib  # type: ignore[no-redef]  # the same API under its 3.10 name
    try:
        return tomllib.loads(path.read_text())
    except OSError as exc:
        raise BenchError(f"{what} {str(path)!r}: cannot read ({exc.strerror})") from None
    except tomllib.TOMLDecodeError as exc:
        raise BenchError(f"{what} {str(path)!r}: not valid TOML: {' '.join(str(exc).split())}") from None


def load_definition(path: str | Path) -> StudyDefinition:
    """The study of definition file ``path``; BenchError naming the file and key."""
    path = Path(path)
    where = f"study definition {str(path)!r}"
    data = _read(path, "study definition")
    unknown = sorted(set(data) - DEFINITION_KEYS)
    if unknown:
        raise BenchError(f"{where}: unknown key {unknown[0]!r}; allowed: {', '.join(sorted(DEFINITION_KEYS))}")
    for key in ("study", "method", "protocol", "space"):
        if key not in data:
            raise BenchError(f"{where}: missing key {key!r}")
    space, params = data["space"], data.get("params", {})
    if not isinstance(space, dict) or not space or not isinstance(params, dict):
        raise BenchError(f"{where}: 'space' must be a non-empty table and 'params' a table")
    for name, values in space.items():
        if not isinstance(values, list) or not values:
            raise BenchError(f"{where}: space.{name} must be a non-empty list of values")
    protocol_path = (path.parent / str(data["protocol"])).resolve()
    protocol = _read(protocol_path, "tuning protocol")
    unknown = sorted(set(protocol) - PROTOCOL_KEYS)
    if unknown:
        raise BenchError(f"tuning protocol {str(protocol_path)!r}: unknown key {unknown[0]!r}; "
                         f"allowed: {', '.join(sorted(PROTOCOL_KEYS))}")
    if "trials" not in protocol:
        raise BenchError(f"tuning protocol {str(protocol_path)!r}: missing key 'trials'")
    options = {k: v for k, v in protocol.items() if k not in ("trials", "description")}
    options["method"] = data["method"]
    options["param"] = [f"{k}={','.join(_value_text(v) for v in vs)}" for k, vs in space.items()]
    if params:
        options["params"] = params
    from studies.storage import study_dir

    name = str(data["study"])
    try:
        study_dir(name)
    except BenchError as exc:
        raise BenchError(f"{where}: {exc}") from None
    return StudyDefinition(name, path, protocol_path, options, int(protocol["trials"]))


def estimate(definition: StudyDefinition) -> dict[str, Any]:
    """Worker-seconds of the study with no trial pruned (an upper bound), from the same
    throughput constants as ``bench grids`` (bench/design/costs.py): per trial, training
    ``episodes x horizon x N`` agent-steps at the training rate, and its intermediate and
    final evaluations (argmax only) at the evaluation rate."""
    from bench.design.costs import rate
    from studies.objective import TrialSettings

    s = TrialSettings.make(**{k: v for k, v in definition.options.items() if k in TrialSettings.model_fields})
    steps = s.horizon * s.n_robots
    train = s.episodes * steps / rate(s.method, "train", s.n_robots)
    checks = -(-s.iterations // s.eval_every) - 1  # intermediate evaluations (the last is the final one)
    evals = (checks * s.report_chunks * s.eval_chunk + s.eval_episodes) * steps / rate(s.method, "eval", s.n_robots)
    per_trial = train + evals
    return {"trials": definition.trials, "trial_s": per_trial, "train_s": train, "eval_s": evals,
            "worker_hours": definition.trials * per_trial / 3600.0, "settings": s}
