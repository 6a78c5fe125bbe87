"""GAIL against its learning rate, as cells (the paper's Figure 4 for GAIL; ``gail_lr.json``).

Cells: on ``hopper`` (11 demonstrations), per learning rate of ``budget.lr_sweep_lrs`` (one rate for the policy,
its critic and the discriminator) and seed of ``budget.seeds_for("hopper")``, GAIL from the
seed's BC warm start for ``budget.lr_sweep_steps`` interactions (variant ``lr=...``).
"""

from dc_lesson.experiments import cells
from dc_lesson.experiments.studies import _common, _imitation as _im
from dc_lesson.experiments.studies._learners import gail_cell, run_gail

NAME = "gail_lr"


def cells_at(b):
    return [gail_cell(NAME, _im.LR_TASK, s, b, lr=lr, steps=b.lr_sweep_steps, variant=f"lr={lr:g}", n_demos=_im.ABLATION_DEMOS,
                      curve=_im.ablation_curve(b))
            for s in b.seeds_for(_im.LR_TASK) for lr in b.lr_sweep_lrs]   # seed-major


STUDY = cells.Study(NAME, "GAIL's final return per learning rate (Figure 4)", cells=cells_at,
                    run_cell=lambda c, n: _common.run_expert_or(c, n, run_gail),
                    aggregate=_im.versus_start_aggregate, result_file="gail_lr.json")
