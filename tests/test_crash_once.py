"""The helper that lets exactly one worker crash."""
from __future__ import annotations

from pathlib import Path

from tests.crash_once import first_claim


def test_first_claim__is_true_once_then_false(tmp_path: Path) -> None:
    marker = str(tmp_path / "died")
    assert [first_claim(marker) for _ in range(3)] == [True, False, False]
    assert Path(marker).exists()
