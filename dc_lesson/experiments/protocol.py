"""What the studies share: evaluation seeds that never replay a demonstration, the seeded
subsample and key of a run's stored mode features, and the protocol of the cell studies: the fresh expert reference every learner is scored against and the expert
row (expert vs expert: the floor of every measure; see the section below)."""

from __future__ import annotations

import numpy as np

from dc_lesson import data as _data
from dc_lesson.data import rollout as _rollout
from dc_lesson import tasks as _tasks


class BenchInputError(ValueError):
    """Seeds a study cannot run with."""


def check_eval_seeds(demos: _data.Demonstrations, eval_seed: int, n: int) -> None:
    """Refuses evaluation seeds whose episodes would start where a demonstration started."""
    clash = set(_rollout.episode_seeds(eval_seed, n).tolist()) & {t.seed for t in
                                                                   demos.trajectories}
    if clash:
        raise BenchInputError(f"evaluation seed {eval_seed} gives {len(clash)} episode(s) that "
                              f"start where a {demos.task} demonstration started; choose "
                              f"another")


def subsample(x: np.ndarray, n: int, seed: int = 0) -> np.ndarray:
    """At most ``n`` rows of ``x`` (a seeded subsample in order, float32)."""
    x = np.asarray(x, dtype=np.float32)
    if len(x) <= n:
        return x
    return x[np.sort(np.random.default_rng(seed).choice(len(x), n, replace=False))]


def feature_key(task: str, method: str, seed: int | None = None) -> str:
    return f"{task}__{method}" + ("" if seed is None else f"__seed{seed}")


__all__ = ["BenchInputError", "check_eval_seeds", "feature_key", "subsample"]


# -- the fresh reference and the expert row -------------------------------------------------------
#
# Learners are scored against fresh expert episodes, never against the demonstrations they
# trained on: the reference is REFERENCE_EPISODES episodes of the task's expert from
# REFERENCE_SEED's initial states (a cell of the study "reference", collected once per task and
# read by every study).  The expert row scores the expert itself, by the same protocol, on the
# learners' evaluation episodes (seed 0: EVAL_SEED, the very episodes every learner is run on)
# and on further disjoint samples (seed s > 0: EVAL_SEED + s): two disjoint expert samples, the
# floor below which a learner's EMD / KL / RKL mean nothing.  (For the planner experts of
# walker, ant and humanoid an episode costs minutes, so their reference costs
# REFERENCE_EPISODES of those; no study of this package uses those tasks yet.)

REFERENCE_SEED = 3000
REFERENCE_EPISODES = 25     # as many episodes as the stored demonstrations
REFERENCE_STUDY = "reference"


class Reference:
    """Fresh expert episodes' mode features (what :func:`evaluation.evaluate_policy` compares a
    learner with), with where they came from."""

    def __init__(self, task: str, mode_features: np.ndarray, seed: int, n_episodes: int,
                 mode_shares: dict | None = None):
        self.task, self.seed, self.n_episodes = task, int(seed), int(n_episodes)
        self.mode_features = np.asarray(mode_features, np.float32)
        self.mode_shares = mode_shares


def _clash(seed_a: int, n_a: int, seed_b: int, n_b: int) -> set:
    return (set(_rollout.episode_seeds(seed_a, n_a).tolist())
            & set(_rollout.episode_seeds(seed_b, n_b).tolist()))


def check_disjoint(task: str, samples: dict[str, tuple[int, int]]) -> None:
    """Refuses samples (name -> (seed, episodes)) that share an initial state with each other or
    with a demonstration of ``task``."""
    demo_seeds = {t.seed for t in _data.load_demos(task).trajectories}
    names = list(samples)
    for i, a in enumerate(names):
        sa, na = samples[a]
        if set(_rollout.episode_seeds(sa, na).tolist()) & demo_seeds:
            raise BenchInputError(f"{task}: the {a} episodes (seed {sa}) start where a "
                                  f"demonstration started; choose another seed")
        for b in names[i + 1:]:
            if _clash(sa, na, *samples[b]):
                raise BenchInputError(f"{task}: the {a} and {b} episodes share initial states; "
                                      f"choose other seeds")


def expert_eval_seed(seed: int) -> int:
    """The evaluation seed of the expert row's sample ``seed`` (0: the learners' episodes)."""
    from dc_lesson import evaluation
    return evaluation.EVAL_SEED + int(seed)


def reference_cell(task: str, episodes: int = REFERENCE_EPISODES, seed: int = REFERENCE_SEED):
    from dc_lesson.experiments import cells
    expert = _data.manifest_entry(task)["expert"]["name"]   # the demonstrations' expert
    return cells.make_cell(REFERENCE_STUDY, "expert", task, 0, seed,
                           {"kind": "fresh expert episodes", "episodes": int(episodes),
                            "episode_seed": int(seed), "expert": expert},
                           stage=0)


def run_reference(cell, needs=()) -> tuple[dict, dict]:
    """Collects the reference episodes of a :func:`reference_cell`."""
    from dc_lesson import evaluation
    from dc_lesson.experts import load_expert
    from dc_lesson.evaluation import metrics
    cfg = cell.config
    check_disjoint(cell.task, {"reference": (cfg["episode_seed"], cfg["episodes"]),
                               "evaluation": (evaluation.EVAL_SEED, 50)})
    expert, _ = load_expert(cell.task)
    trajs = _rollout.collect(cell.task, expert, cfg["episodes"], seed=cfg["episode_seed"],
                             progress=False)
    multi = len(_tasks.spec(cell.task).modes) > 1
    result = {"returns": [float(t.ret) for t in trajs],
              "return_mean": float(np.mean([t.ret for t in trajs])),
              "mode_shares": metrics.mode_shares(cell.task, trajs) if multi else None,
              "n_states": int(sum(len(t.mode_features) - 1 for t in trajs))}
    return result, {"features": evaluation.learner_features(trajs)}


def reference_from(record: dict, features: dict) -> Reference:
    """The :class:`Reference` of a finished reference cell (its stored float32 features, so a
    cell run right after the reference and one run a day later see the same numbers)."""
    c = record["cell"]
    return Reference(c["task"], features["features"], c["seed"],
                     record["config"]["episodes"], record["result"]["mode_shares"])


def expert_row_cell(study: str, task: str, seed: int, eval_episodes: int, emd_n_max=2000):
    """The expert scored like a learner: sample ``seed`` of its episodes against the reference."""
    from dc_lesson.experiments import cells
    ref = reference_cell(task)
    return cells.make_cell(study, "expert", task, 0, seed,
                           {"eval_episodes": int(eval_episodes),
                            "eval_seed": expert_eval_seed(seed), "emd_n_max": emd_n_max,
                            "policy": "the task's expert (experts.load_expert)"},
                           needs=(ref,))


def run_expert_row(cell, needs) -> tuple[dict, None]:
    from dc_lesson import evaluation
    from dc_lesson.experts import load_expert
    cfg = cell.config
    reference = reference_from(*needs[0])
    check_disjoint(cell.task, {"reference": (reference.seed, reference.n_episodes),
                               "expert sample": (cfg["eval_seed"], cfg["eval_episodes"])})
    expert, _ = load_expert(cell.task)
    ev = evaluation.evaluate_policy(cell.task, expert, reference,
                                    n_episodes=cfg["eval_episodes"], seed=cfg["eval_seed"],
                                    emd_n_max=cfg["emd_n_max"])
    return {"measures": measures_of(ev)}, None


MEASURED = ("scaled_return", "return", "return_std", "emd", "kl", "rkl", "mode_shares")


def measures_of(ev: dict) -> dict:
    """The stored measures of an :func:`evaluation.evaluate_policy` result."""
    return {k: ev[k] for k in MEASURED}


__all__ += ["MEASURED", "REFERENCE_EPISODES", "REFERENCE_SEED", "Reference", "check_disjoint",
            "expert_eval_seed", "expert_row_cell", "measures_of", "reference_cell",
            "reference_from", "run_expert_row", "run_reference"]
