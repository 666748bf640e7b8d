"""One real hierarchical trial at toy scale through the study's worker (runtime ~5 s)."""
from __future__ import annotations

import pytest

from studies.objective import TrialSettings, TrialWorker, eval_seed

pytest.importorskip("algorithms.hierarchical.method")


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::UserWarning")
def test_hierarchical_trial__segments_run_and_repeat_exactly() -> None:
    settings = TrialSettings.make(n_robots=4, horizon=12, episodes=4, batch_episodes=2,
                                  eval_every=1, eval_episodes=4, eval_chunk=2)
    sampled = {"ref_size": 4, "search_radius": 1}

    def run() -> list[tuple[int, float, float]]:
        worker = TrialWorker(settings.spec(sampled, seed=11, eval_seed=eval_seed(0)))
        assert worker.method.params.ref_size == 4 and worker.method.params.search_radius == 1
        segments = [worker.step(), worker.step()]
        # its filter ran: both rates recorded
        assert all(0.0 <= s.fallback_rate <= 1.0 and 0.0 <= s.correction_rate <= 1.0 for s in segments)
        return [(s.step, s.success_rate, s.team_return) for s in segments]

    first = run()
    assert [step for step, _, _ in first] == [1, 2]
    assert all(0.0 <= success <= 1.0 for _, success, _ in first)
    assert run() == first  # a trial is a pure function of its seed
