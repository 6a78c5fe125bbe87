"""Expert policies that produce the demonstrations the learners imitate.

``scripted`` holds hand-designed controllers (no learning) for the tasks where one is easy to
write: an LQR for ``cartpole`` and inverse kinematics + PD for the reachers.  ``trained``
holds the PPO experts of hopper and the cheetahs; ``network`` those of walker, ant and
humanoid (SAC, distilled into the learners' GaussianPolicy); ``planner`` a sampling-based
planner on the true simulator (predictive sampling), these three tasks' first experts: it
meets the floors but is no Markov policy, so BC cannot clone it. ``DEFAULT_EXPERT`` says which
of the two is each task's expert; the other is its variant.
"""

from __future__ import annotations


# The default expert of the three tasks that have both a sampling planner and a SAC network
# (experts.network): the network where it meets the task's floor (the other is the variant).
# All three meet it (the humanoid since its second SAC recipe; the first run's curve stays in
# data/experts/humanoid-fall.json).
DEFAULT_EXPERT = {"walker": "network", "ant": "network", "humanoid": "network"}
VARIANTS = {"reacher2": ("coin",), "reacher4": ("coin",), "halfcheetah2": ("coin",),
            **{t: ("planner" if kind == "network" else "network",)
               for t, kind in DEFAULT_EXPERT.items()}}

# The mode shares the realizable experts' choice rules give over start states (measured on the
# first observations of seeds 0..9999: reachers, the target nearest the start; halfcheetah2,
# the back thigh's angle against its median).  25 demonstrations deviate by sampling alone.
EXPECTED_SHARES = {"reacher2": (0.498, 0.502), "reacher4": (0.252, 0.254, 0.252, 0.243),
                   "halfcheetah2": (0.488, 0.512)}


def load_expert(task: str, variant: str | None = None):
    """The expert of ``task`` as a batch policy, and a JSON-able description of it.

    Scripted controllers for ``cartpole`` and the reachers; network policies (PPO, or SAC
    distilled into a GaussianPolicy: ``dc-lesson expert train``) for the others, read from
    ``data/experts/``; on walker, ant and humanoid the sampling planner or the SAC network,
    whichever ``DEFAULT_EXPERT`` names, the other as the variant (``"planner"``,
    ``"network"``).

    The multi-mode experts choose their mode from the observed start state (the nearest
    target; the back thigh's starting angle), so a Markov policy can follow them; the variant
    ``"coin"`` (``VARIANTS``) chooses by a hidden coin flip per episode instead, which no
    Markov unimodal policy can follow (chapter 04).
    """
    from dc_lesson import tasks
    from dc_lesson.experts import scripted
    tasks.check_name(task)
    if variant is not None and variant not in VARIANTS.get(task, ()):
        raise ValueError(f"{task} has no expert variant {variant!r}; the variants are: "
                         + (", ".join(VARIANTS.get(task, ())) or "none"))
    if task in scripted.SCRIPTED_TASKS:
        policy = scripted.expert_for(task, variant)
        return policy, scripted.describe(task, variant)
    if task in DEFAULT_EXPERT:
        kind = variant or DEFAULT_EXPERT[task]
        if kind == "planner":
            from dc_lesson.experts import planner
            return planner.load_planner_expert(task)
        from dc_lesson.experts import trained
        return trained.load_trained_expert(task)
    from dc_lesson.experts import trained
    return trained.load_trained_expert(task, variant=variant)
