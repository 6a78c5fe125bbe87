"""DC against its learning rate, as cells (the paper's Figure 4 for DC; ``dc_lr.json``): on
``hopper`` (11 demonstrations), per learning rate of ``budget.lr_sweep_lrs`` (both copies' AdamW) and seed,
``budget.lr_sweep_steps`` interactions from the seed's BC warm start (variant ``lr=...``)."""

from dc_lesson.experiments import cells
from dc_lesson.experiments.studies import _common, _imitation as _im
from dc_lesson.experiments.studies._learners import dc_cell, run_dc

NAME = "dc_lr"


def cells_at(b):
    return [dc_cell(NAME, _im.LR_TASK, s, b, overrides={"lr": float(lr)},
                    steps=b.lr_sweep_steps, variant=f"lr={lr:g}", n_demos=_im.ABLATION_DEMOS,
                    curve=_im.ablation_curve(b))
            for s in b.seeds_for(_im.LR_TASK) for lr in b.lr_sweep_lrs]   # seed-major


STUDY = cells.Study(NAME, "DC's final return per learning rate (Figure 4)", cells=cells_at,
                    run_cell=lambda c, n: _common.run_expert_or(c, n, run_dc),
                    aggregate=_im.versus_start_aggregate, result_file="dc_lr.json")
