"""Expert policies that produce the demonstrations the learners imitate.

``scripted`` holds hand-designed controllers (no learning) for the tasks where one is easy to
write: an LQR for ``cartpole`` and inverse kinematics + PD for the reachers.  ``trained``
holds the PPO experts of the locomotion tasks; ``planner`` a sampling-based planner on the
true simulator (predictive sampling), the expert where PPO on this CPU falls short.
"""

from __future__ import annotations


def load_expert(task: str):
    """The expert of ``task`` as a batch policy, and a JSON-able description of it.

    Scripted controllers for ``cartpole`` and the reachers; the planner for the tasks in
    ``planner.PLANNERS``; network policies trained with PPO (``dc-lesson expert train``) for
    the others, read from ``data/experts/``.
    """
    from dc_lesson import tasks
    from dc_lesson.experts import scripted
    tasks.check_name(task)
    if task in scripted.SCRIPTED_TASKS:
        policy = scripted.expert_for(task)
        return policy, scripted.describe(task)
    from dc_lesson.experts import planner
    if task in planner.PLANNERS:
        return planner.load_planner_expert(task)
    from dc_lesson.experts import trained
    return trained.load_trained_expert(task)
