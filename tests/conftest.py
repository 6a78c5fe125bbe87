import os

# Headless rendering for tests, whatever the machine (set before dm_control is imported).
os.environ.setdefault("MUJOCO_GL", "egl")


import pytest  # noqa: E402


@pytest.fixture(autouse=True, scope="session")
def one_thread():
    """One torch thread: the machine's cores are shared, and one thread makes runs repeat to
    the last digit."""
    import torch
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


@pytest.fixture
def judge_every_learner(monkeypatch):
    """Verdict rules on constructed records: no learner is held back by the stored competence
    gate (its rules and its reach are tested in test_competence.py)."""
    from dc_lesson.experiments import competence
    monkeypatch.setattr(competence, "mapping", lambda rec=None: {})
    monkeypatch.setattr(competence, "under_gate", lambda *grids: True)
