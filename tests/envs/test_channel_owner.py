"""The environment owns the lossy channel: no module outside envs/ builds one.

Methods and the PettingZoo adapter open the channel through ``envs.channel.open_channel``
(``EpisodeBatch.open_channel`` for methods); a ``LossProcess``, ``Channel`` or
``GroupChannel`` constructed anywhere else would be a second, private channel whose loss
(and delay) could drift from the environment's.
"""
from __future__ import annotations

import re
from pathlib import Path

from tests.source_scan import code_matches

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("algorithms", "bench", "reports", "studies", "scripts", "examples")
BUILDS = re.compile(r"\b(LossProcess|GroupChannel|Channel)(\.from_config)?\(")


def channel_builders(base: Path, folders: tuple[str, ...]) -> list[str]:
    """'path:line' (relative to ``base``) of every construction of a channel class in the
    Python files under ``base / folder`` (comments ignored)."""
    return [f"{rel}:{k}" for rel, k, _ in code_matches(base, folders, BUILDS)]


def test_channel_is_constructed_only_in_envs():
    assert channel_builders(ROOT, PACKAGES) == []


def test_channel_builders__finds_a_construction(tmp_path):
    (tmp_path / "algorithms").mkdir()
    (tmp_path / "algorithms" / "m.py").write_text(
        "x = 1\nloss = LossProcess.from_config((1, 2, 2), env, rng)\n"
        "ch = GroupChannel(env, 1, rng)  \n# Channel(x) in a comment\nc = open_channel(env, 1, rng)\n")
    assert channel_builders(tmp_path, ("algorithms",)) == ["algorithms/m.py:2", "algorithms/m.py:3"]
