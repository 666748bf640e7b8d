"""The search space and its user overrides (runtime < 1 s)."""
from __future__ import annotations

import pytest
from optuna.distributions import CategoricalDistribution

from envs.errors import BenchError
from studies.space import distributions, parse_overrides, search_space, space_size


def test_space__default_is_ref_size_and_search_radius_exactly() -> None:
    assert search_space() == {"ref_size": (2, 4, 8, 16, 32), "search_radius": (0, 1, 2, 3)}
    assert space_size(search_space()) == 20


def test_space__c_max_joins_only_on_request() -> None:
    space = search_space(c_max=True)
    assert list(space) == ["ref_size", "search_radius", "c_max"]
    assert 500 in space["c_max"]  # the paper's C_max (Sec. IV)


def test_space__override_restricts_and_sorts_choices() -> None:
    space = search_space(overrides={"search_radius": [3, 1, 1]})
    assert space == {"ref_size": (2, 4, 8, 16, 32), "search_radius": (1, 3)}


@pytest.mark.parametrize("overrides, message", [
    ({"radius": [1]}, "unknown study parameter 'radius'"),
    ({"ref_size": []}, "empty range"),
    ({"search_radius": [-1]}, ">= 0"),
    ({"ref_size": ["x"]}, "integers"),
])
def test_space__bad_override_is_one_clear_error(overrides: dict, message: str) -> None:
    with pytest.raises(BenchError, match=message):
        search_space(overrides=overrides)


def test_parse_overrides__lists_and_inclusive_ranges() -> None:
    assert parse_overrides(["ref_size=4,8", "search_radius=1..3"]) == {
        "ref_size": [4, 8], "search_radius": [1, 2, 3]}


@pytest.mark.parametrize("text, message", [
    ("ref_size=", "empty range"),
    ("search_radius=3..1", "empty range"),
    ("foo=1", "unknown study parameter 'foo'"),
    ("ref_size", "expected NAME=V1,V2"),
    ("ref_size=a,b", "cannot parse"),
])
def test_parse_overrides__bad_text_is_one_clear_error(text: str, message: str) -> None:
    with pytest.raises(BenchError, match=message):
        parse_overrides([text])


def test_distributions__categorical_over_the_choices() -> None:
    dists = distributions(search_space())
    assert dists["ref_size"] == CategoricalDistribution([2, 4, 8, 16, 32])
    assert dists["search_radius"] == CategoricalDistribution([0, 1, 2, 3])


def test_method_space__parses_by_each_hyperparameter_type_and_validates_with_the_method() -> None:
    from studies.space import method_space

    space = method_space("hierarchical", {"lr": ["3e-3", "1e-3"], "share_params": ["true", "false"],
                                          "messages": ["oracle"], "search_radius": ["1..2"]})
    assert space == {"search_radius": (1, 2), "lr": (0.001, 0.003), "messages": ("oracle",),
                     "share_params": (False, True)}


@pytest.mark.parametrize("overrides, message", [
    ({"lr": ["-1"]}, "lr: -1.0: Input should be greater than 0"),
    ({"lr": ["fast"]}, "cannot parse 'fast' as a number"),
    ({"share_params": ["yes"]}, "true/false"),
    ({"messages": ["telepathy"]}, "messages: 'telepathy'"),
    ({"nope": ["1"]}, "unknown study parameter 'nope' for method decentralized"),
    ({"batch_episodes": ["4"]}, "part of the tuning budget"),
    ({}, "give the parameters to tune"),
])
def test_method_space__bad_parameter_is_one_clear_error(overrides: dict, message: str) -> None:
    from studies.space import method_space

    method = "hierarchical" if set(overrides) & {"share_params", "messages"} else "decentralized"
    with pytest.raises(BenchError, match=message):
        method_space(method, overrides)


def test_method_space__a_planner_has_nothing_to_tune() -> None:
    from studies.space import method_space

    with pytest.raises(BenchError, match="planner"):
        method_space("pibt", {"eval_chunk": ["2"]})
