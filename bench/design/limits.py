"""Upper bounds on every count a user can type, each with its reason (D4, SPEC 7).

A count without a bound is accepted and then fails far from where it was typed: an
``eval_episodes = 10**12`` grid file held the driver at 4 GB after a minute. The bounds are
generous (100x to 1000x what the paper runs) and exist to turn a typo into a message at
the start. ``reason(field)`` is appended to the validation message; adding a bound changes
no cell id (the id hashes the values, which a bound does not touch).
"""
from __future__ import annotations

from pydantic_core import ErrorDetails

# field -> (largest value, why). The paper (Sec. IV): N <= 100, T = 500, 2000 episodes,
# 100 evaluation episodes, |R_z| = 8, L = 2, C_max = 500, 3 seeds.
LIMITS: dict[str, tuple[int, str]] = {
    "n_robots": (10_000, "100x the paper's largest team; observations grow with N x N"),
    "horizon": (10_000, "20x the paper's 500 steps; rollout arrays grow with T x N x batch"),
    "episodes": (1_000_000, "500x the paper's 2000; training rows and time grow with it"),
    "eval_episodes": (100_000, "1000x the paper's 100; the driver holds a cell's evaluation rows in memory "
                               "until its eval file is written"),
    "groups": (1_000, "groups Z of at least one robot each; the paper uses 4"),
    "ref_size": (4_096, "one output of the reference policy per reference; the paper's |R_z| is 8"),
    "search_radius": (64, "the safety filter's candidates grow as (2L+1)^2 per robot; the paper's L is 2"),
    "c_max": (1_000_000, "candidates the safety filter may examine per group-step; the paper's C_max is 500"),
    "seeds": (1_000, "every configuration runs once per seed: K seeds make K times the cells"),
    "workers": (1_024, "one worker actor per core"),
    "trials": (100_000, "each trial trains a method"),
    "replicates": (1_000, "each replicate trains every configuration again"),
    "stack_seeds": (1_024, "cells trained together in one worker"),
    "checkpoint_every": (1_000_000, "training iterations between checkpoints"),
    "episode": (100_000, "evaluation episodes are fewer than eval_episodes"),
}


def limit(field: str) -> int:
    return LIMITS[field][0]


def reason(field: str) -> str:
    """' (limit L: why)' for a bounded field, else ''."""
    if field not in LIMITS:
        return ""
    top, why = LIMITS[field]
    return f" (limit {top}: {why})"


def with_reasons(err: ErrorDetails, text: str) -> str:
    """``text`` (one pydantic error's message) plus the reason of the bound it broke."""
    if err.get("type") in ("less_than_equal", "less_than"):
        return text + reason(str(err["loc"][-1]) if err.get("loc") else "")
    return text


def check_count(option: str, field: str, value: int | None) -> None:
    """BenchError naming ``option`` when ``value`` exceeds the bound of ``field``."""
    from envs.errors import BenchError

    if value is not None and value > limit(field):
        raise BenchError(f"{option} {value} is too large{reason(field)}")
