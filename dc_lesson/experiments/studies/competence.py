"""Is each RL learner a competent implementation? The gate every learner passes before it
judges a claim of the paper (issue 38; ``dc-lesson sweep competence``, ``competence.json``).

Two questions, each a part of the grid, every RL learner of the book (PPO on the task's own
reward as the RL base, then GAIL, DRIL, PWIL, NDI, GPRIL and DC), one seed's start shared by
all of them, and chapter 04's DC with a mixture policy from its own start (:data:`VARIANTS`):

* **keeps a perfect start** (``part="keep"``): from the BC warm start on 4 demonstrations of
  :data:`KEEP_TASKS` (where BC is already at the expert's level), ``competence_keep_steps``
  interactions; the mean-action scaled return of the final policy and at
  ``competence_curve_points`` checkpoints.  Passed when the final policy is within
  :data:`KEEP_TOLERANCE` of its start (or above) on at least :data:`KEEP_SHARE` of the seeds of
  every task, and no checkpoint falls more than :data:`MAX_DIP` below the start, except on a
  task whose start is *knife-edge* (:func:`knife_edge`, from the ``start_noise`` study: random
  weight noise the size of a few learner iterations fells it), where the dips are shown and
  the finals rule alone decides.
* **learns** (``part="learn"``): from a *weak* start on :data:`LEARN_TASKS` (BC on the same 4
  demonstrations stopped after ``competence_weak_epochs`` epochs: a policy that has seen the
  demonstrations but not fitted them; chosen because the benchmark's demonstration protocol,
  issue 41, is not settled, and because it needs no change of the demonstrations), for
  ``competence_learn_steps`` interactions, with checkpoint curves: the learning curves that
  set every later grid's budget.  Passed when the mean final scaled return over the seeds
  reaches :data:`LEARN_FLOOR` on every task.  A start that is not weak (mean above
  :data:`WEAK_CEILING`) makes the question uninformative: the gate then says so instead of
  passing.

:func:`gate` turns the aggregate into one word per learner ("passed", or "failed the
competence gate: <why>", or not yet decided while a part has seeds still to run and none of
its failures is already certain: :func:`so_far`); :func:`competence` gives the mapping
``verdicts`` reads, so a comparison whose comparator failed is "not judged".  The thresholds
are the issue's, declared before any cell ran.

Every learner runs with two shared rules (:func:`learner_config`), each chosen by a measured
probe and each a named field of the learner's config: its start's exploration noise set to
``algorithms.base.START_LOG_STD`` (``start_log_std``), and on hopper the training-only fall
termination its expert trained with (``ppo.terminate``, :data:`TERMINATE`).
"""

from __future__ import annotations

import dataclasses
import json
import math
from typing import NamedTuple

import numpy as np

from dc_lesson import algorithms as _algorithms
from dc_lesson import storage as _storage
from dc_lesson import budget as _budget
from dc_lesson import evaluation as _evaluation
from dc_lesson.algorithms import base as _base
from dc_lesson.algorithms import bc as _bc
from dc_lesson.data import store as _store
from dc_lesson.experiments import cells, protocol
from dc_lesson.experiments.studies import _common, _imitation as _im
from dc_lesson.experiments.studies import table1 as _t1
from dc_lesson.experiments.studies import _mixture_match as _match
from dc_lesson.nn import mixture as _mixture

NAME = "competence"
# The mixture variants the book judges (issue 38 asks for them too): DC with the
# 4-component mixture policy (``nn.mixture``), chapter 04's ``dc-mix`` rows.  Its cells run
# DC's own gated config from the start those rows have (:func:`mixture_start`): to keep, the
# mixture BC trained until it matches plain BC (``_mixture_match``, ``modes``' rule, on these
# 4 demonstrations); to learn, the mixture BC after the weak start's epochs; each with
# its spreads set to the gate's exploration noise.  A keep part with a seed whose mixture
# did not match is not informative (:func:`keeps`): a start that is not perfect cannot be
# kept.  A start matches when its match record did (the match episodes) *and* it scored, on
# the gate's own evaluation episodes, within KEEP_TOLERANCE of the same seed's Gaussian
# start (:func:`judge_starts`).  Declared before any of its cells ran but the first (seed 0,
# cartpole: matched on the match episodes, 0.75 on the gate's against the Gaussian's 1.00,
# which is why the second condition was added).  Its dips on hopper are not gated, like every
# learner's there: the knife-edge measurement (``start_noise``) is of the Gaussian starts,
# and is taken to hold for the mixture's (not measured).  Why a keep part can be unasked: an
# unstored probe (6 December; the mixture BC as ``modes`` trains it, lesson, 20 episodes) scored its
# mean action 0.40 on cartpole's 4 demonstrations (seed 0; plain BC 1.00), and 0.17 / 0.31 /
# 0.27 (seeds 0-2) trained as the Gaussian start is (70/30, early stopping).  The Gaussian's
# form inside the mixture (one state-independent spread per component, near-zero initial
# means) cloned cartpole (0.96) but not reacher4 (0.26, against the mixture's 0.88 and plain
# BC's 0.92), so the mixture stays as ``nn.mixture`` has it.
VARIANTS = {"dc-mix": "dc"}
LEARNERS = ("ppo", "gail", "dril", "pwil", "ndi", "gpril", "dc", *VARIANTS)
CONTROL = "ppo"   # the RL base on the task's own reward: a control, run by no later grid
KEEP_TASKS = ("cartpole", "hopper")
LEARN_TASKS = ("hopper", "halfcheetah")
N_DEMOS = 4
KEEP_TOLERANCE = 0.05    # final within this of the start (scaled return) ...
KEEP_SHARE = 0.9         # ... on at least this share of the seeds
MAX_DIP = 0.2            # and no checkpoint more than this below the start
LEARN_FLOOR = 0.8        # mean final scaled return from the weak start
WEAK_CEILING = 0.5       # a start above this is not weak: the learns question is uninformative

# Where the dip rule says something about the learner.  Decided in the fourth week of the study,
# after DC's and GAIL's hopper keep cells and one seed of PPO's, and argued in chapter 5: on
# hopper every learner that moves its weights dips, PPO on the task's own reward (seed 0:
# 0.30 at the first checkpoint), imitation 1.0.1's GAIL at its tuned settings (seed 3:
# 0.11), GAIL, DC (3 of 10 seeds) alike, and the ``start_noise`` study shows why: Gaussian
# noise of s = 3e-3 on every weight (a weight moves 0.8 s on average, about five DC
# iterations' displacement, 4-7e-4 each by an unstored probe of its training log; the first
# checkpoint comes after about thirteen) fells 16 of 30 copies of the hopper starts and
# none of cartpole's.  A start is *knife-edge* when more than ``KNIFE_EDGE_SHARE`` (the
# share of seeds the keep rule lets fail) of its copies fall at ``STEP_SCALE``; there a
# checkpoint's fall measures the start, not the learner, so the dip is shown and not gated,
# and the learner keeps the start by where it ends (the finals rule, unchanged).  With no
# ``start_noise`` record every task's dip is gated, as declared.
STEP_SCALE = 3e-3
KNIFE_EDGE_SHARE = 1 - KEEP_SHARE
NOISE_RESULT = "start_noise.json"


def _steps(b, part: str) -> int:
    return b.competence_keep_steps if part == "keep" else b.competence_learn_steps


# The training-only termination each task's expert needed (the hopper's PPO: a fallen hopper
# ends its training episode), for every learner that steps the task through PPO's loop
# (PPO, GAIL, DRIL, PWIL, NDI, DC) or its own (GPRIL: a fall ends the episode). Measured (issue 38's
# probe, hopper from a perfect BC start, 100,000 interactions, start log-std -2, seeds 0-2):
# without it PPO ended at 0.95 / 0.30 / 0.22, GAIL 1.00 / 1.00 / 0.31, DC 1.00 / 1.00 / 0.31;
# with it PPO 0.96 / 1.00 / 0.99, GAIL 0.96 / 0.98 / 1.01, DC 1.00 / 1.00 / 0.93.
TERMINATE = {"hopper": "hopper-fall"}


# Settings of one learner that the study's probes chose (issue 38), each a named field of its
# config ("ppo.x": a field of its PPO settings), applied on top of the shared rules.
# GAIL (cartpole from a perfect BC start, 400,000 interactions, seeds 3, 4, 6 and 0; the
# worst checkpoint's fall below the start): its preset fell 0.76 / 0.70 / 0.74 (seed 0 not
# run); with the expert's actions given the learner's noise and advantages not standardised
# (a flat reward then gives small steps instead of unit-size ones), 0.21 / 0.00 / 0.25 / 0.54.
# Tried and not adopted, same seeds: a gradient penalty of 10 (1M interactions, seeds 0-1:
# 0.76, 1.05), a state-only D (up to 0.85), the expert noise alone (0.70-0.76), unstandardised
# advantages alone (0.23-0.46), and on top of both: lr 1e-4 (0.65 on seed 3), 10 critic-only
# iterations (0.99 on seed 0), target_kl 0.005 (0.64 on seed 6).
# GPRIL (same setting, seeds 0-3; its preset at smoke lost 0.78-0.89 of its start on
# seeds 0-2): with the predecessors' weight w at 0.1 instead of 1 it ended at 1.00 on all
# four, its worst checkpoint 0.00 / 0.00 / 0.20 / 0.00 below the start. Predecessors
# sampled from flows still fitting the learner's first batches are noise, and at w = 1
# they weigh as much as the expert's own pairs.
# NDI (same setting, seeds 0-3): with advantages not standardised its entropy bonus (lambda
# 0.01) still dropped it 0.63 and 0.33 at a checkpoint on two seeds; with lambda 0 as well,
# at most 0.17 on all four. NDI here is then its density reward log q(s, a) alone: the
# book says so wherever NDI is judged (a bounded bonus that cannot dominate is still open).
# GAIL after the study's cells (fifth week; probes of one config change on the study's own
# cells, not stored): its cells fail cartpole keep (2 of 10 seeds end below, checkpoints down
# to 0.26) and hopper learn (mean 0.53; curves reach 0.9-0.99 around 1.3M, then fall).  A
# gradient penalty of 10 fixes learning (hopper learn seeds 1 / 3: 0.94 / 0.93, no late fall)
# but breaks keeping (cartpole keep, 1M, seeds 6 / 0: checkpoints down to 0.02 / 0.33);
# imitation 1.0.1's tuned hopper PPO settings (lr 4.4e-5, clip 0.1, 20 epochs, gamma 0.995,
# GAE 0.98, entropy 0.00126) keep (cartpole keep, 400k, seeds 6 / 2 / 0: worst 0.79 / 1.00 /
# 0.81, finals 1.00) but barely learn (hopper learn seed 1: 0.40), as imitation's own GAIL
# (0.67 / 0.15 / 0.16 on seeds 0-2); both together learn (seed 1: 0.86) and fall from a
# start again (cartpole keep 400k, seed 0: final 0.89, worst 0.62).  No setting tried passes
# both parts, so none is adopted: GAIL stays as it is, failing the gate, and the book says so.
# PWIL (sixth week; probes of one config change on the study's own cells, not stored): its
# preset does not learn hopper from the weak start (stored cells: seed 1 0.04 -> 0.07, seed
# 0 0.01 -> 0.15). Its own reward does rise (seed 1, 200,000 interactions: 0.05 -> 0.33 per
# step) while the task's return stays near the start's: at beta = 5 the kernel
# exp(-beta T c / sqrt(d)) is a fraction of an expert standard deviation wide in units of the
# learner's distance, so only states next to the expert's first ones pay, and standing there
# is what PPO finds.  A kernel five times wider (beta = 1) pays along the way: hopper learn
# seeds 1 / 3: 0.04 -> 0.94, 0.02 -> 0.89; cartpole keep seeds 2 / 8: finals 1.00 / 1.00,
# worst checkpoints 0.86 / 0.72 (the preset's 0.69 / 0.73); halfcheetah learn seed 0: 0.20.
# State-only atoms (use_actions=False) did not help (hopper learn seed 1: 0.05).  beta is
# the paper's named hyperparameter, so PWIL stays PWIL; adopted.
# DRIL (seventh week; probes of one config change on the study's own cells, not stored): its
# cells keep hopper and learn both tasks but end below the cartpole start on 4 of 10 seeds
# (finals 0.89 / 0.81 / 0.81 / 0.59, seeds 0 / 2 / 3 / 7).  Seed 2 (an unstored probe, 100,000
# interactions, 5 episodes) still balances from 4 starts and loses the one from cart position
# -0.07 (451 of 1000): a start its 4 demonstrations do not cover.  There the ensemble
# disagrees, so nearly every action is paid -1 (a^T Cov a spares only the smallest) and
# little but the BC steps holds the policy to what BC had learnt.  Our 8 BC steps of
# 256 pairs per 4096 interactions were a third of the authors' rate (their code: one epoch of
# batch 100 over 80% of the pairs per PPO update of 2048 interactions: about 25 such steps
# here).  Probes, cartpole keep: 16 steps, seeds 7 / 0 / 2 / 3: finals 1.00 on all four,
# worst checkpoints 1.00 / 1.00 / 0.80 / 0.80; 32 steps, seeds 3 / 2: worst 1.00 / 0.83;
# halfcheetah learn seed 0 at 16: 0.98 (the preset's 0.80).  Adopted: DC's own balance rule,
# as many BC steps as PPO takes minibatch steps per iteration (ppo.n_epochs x
# ppo.n_minibatches = 5 x 8 = 40 at every budget; a test holds the number to the rule), so the
# book's two BC + RL hybrids weigh BC alike and differ in their rewards.  Not adopted: 20
# critic-only iterations with lr 1e-4 (seed 0: final 0.81, the same lost start).


FIXES: dict[str, dict] = {
    "gail": {"expert_noise": "learner", "ppo.norm_adv": False},
    "dril": {"bc_steps": 40},
    "pwil": {"beta": 1.0},
    "ndi": {"entropy_coef": 0.0, "ppo.norm_adv": False},
    "gpril": {"predecessor_weight": 0.1},
}


def _with(cfg, settings: dict):
    for name, value in settings.items():
        if name.startswith("ppo."):
            cfg = dataclasses.replace(cfg, ppo=dataclasses.replace(cfg.ppo, **{name[4:]: value}))
        else:
            cfg = dataclasses.replace(cfg, **{name: value})
    return cfg


def algorithm(learner: str) -> str:
    """The registered algorithm a gated row runs (``dc-mix``: ``dc``)."""
    return VARIANTS.get(learner, learner)


def learner_config(learner: str, b, part: str, seed: int, task: str | None = None):
    """The learner's config in a cell of ``part``: :func:`gated_config` at the part's
    interactions."""
    return gated_config(learner, b, _steps(b, part), seed, task)


def gated_config(learner: str, b, steps: int, seed: int, task: str | None = None):
    """The learner's preset for ``steps`` interactions, with two rules every RL learner
    shares, which the grids adopt when they are run again (``studies.benchmark``): its
    start's exploration noise (``algorithms.base.START_LOG_STD``, GAIL's tuned -2) and, on
    ``task``, the training-only termination of ``TERMINATE``; then the learner's own
    :data:`FIXES`."""
    sized = dataclasses.replace(b, il_steps=steps)
    learner = algorithm(learner)
    cfg = dataclasses.replace(_algorithms.get(learner).preset(sized, seed),
                              start_log_std=_base.START_LOG_STD)
    cfg = _with(cfg, FIXES.get(learner, {}))
    end = TERMINATE.get(task)
    if end is not None and hasattr(cfg, "ppo"):
        cfg = dataclasses.replace(cfg, ppo=dataclasses.replace(cfg.ppo, terminate=end))
    elif end is not None:   # PPO itself, GPRIL
        cfg = dataclasses.replace(cfg, terminate=end)
    return cfg


def cells_at(b) -> list[cells.Cell]:
    out = []
    for part, tasks, n_seeds in (("keep", KEEP_TASKS, b.competence_keep_seeds),
                                 ("learn", LEARN_TASKS, b.competence_learn_seeds)):
        for task in tasks:
            for seed in range(n_seeds):
                for learner in LEARNERS:
                    cfg = json.loads(learner_config(learner, b, part, seed, task).to_json())
                    out.append(cells.make_cell(
                        NAME, learner, task, N_DEMOS, seed,
                        {"budget": b.name, "part": part, "steps": _steps(b, part),
                         "start_epochs": (b.bc_max_epochs if part == "keep"
                                          else b.competence_weak_epochs),
                         "eval_episodes": b.competence_eval_episodes,
                         "eval_seed": protocol.expert_eval_seed(0),
                         "curve_points": b.competence_curve_points,
                         "curve_episodes": b.competence_curve_episodes,
                         **({"start_policy": "mixture",
                             "n_components": _t1.N_COMPONENTS,
                             "log_std_min": _mixture.LOG_STD_MIN,
                             "start_training": "bc-full",
                             "match": dict(_match.RULE) if part == "keep" else None}
                            if learner in VARIANTS else {}),
                         learner: _im.without_seed(cfg)}, variant=part))
    out.sort(key=lambda c: (c.seed, c.variant, c.task))   # seed-major: every seed's rows early
    return out


def run_cell(cell, needs):
    c = cell.config
    b = _budget.get(c["budget"])
    cfg = learner_config(cell.learner, b, c["part"], cell.seed, cell.task)
    _im.check_config(cell, json.loads(cfg.to_json()))
    demos = _store.load_demos(cell.task, n_trajectories=cell.n_demos)

    def evaluate(policy, n_episodes):   # scaled return needs no reference
        return _evaluation.evaluate_policy(cell.task, policy, None, n_episodes=n_episodes,
                                           seed=c["eval_seed"], divergences=False)

    if cell.learner in VARIANTS:   # every variant so far starts from a mixture BC
        start, match = _im.cached_start(
            (cell.task, cell.n_demos, "competence", cell.seed, c["start_epochs"], "mixture",
             c["part"]),
            lambda: mixture_start(cell.task, demos, cell.seed, b, c["part"]))
        out = _im.train_from_start(cell, cfg, demos, start, evaluate,
                                   algorithm=algorithm(cell.learner))
        return ({**out, "match": match} if match is not None else out), None
    start = _im.cached_start(   # the seed's start, shared by the learners' cells
        (cell.task, cell.n_demos, "competence", cell.seed, c["start_epochs"], False),
        lambda: _bc.warm_start_policy(demos, cell.seed, max_epochs=c["start_epochs"]))
    return _im.train_from_start(cell, cfg, demos, start, evaluate), None


def mixture_start(task: str, demos, seed: int, b, part: str) -> tuple:
    """``(start, match record or None)`` of a mixture variant's cell (:data:`VARIANTS`):
    to keep, ``_mixture_match.matched_mixture`` (the mixture BC on all the demonstrations,
    trained until its mean action matches plain BC's); to learn, the same training stopped after
    ``competence_weak_epochs``; each component's spread then set to the gate's exploration
    noise, as ``modes`` starts its ``dc-mix`` rows."""
    if part == "keep":
        policy, match = _match.matched_mixture(task, demos, seed, b)
    else:
        cfg = dataclasses.replace(_t1._bc_config(b, seed, True, full=True),
                                  epochs=b.competence_weak_epochs)
        policy, match = _bc.train(task, demos, cfg, progress=False).policy, None
    return _t1._mixture_start(policy, _base.START_LOG_STD), match


# -- the gate ----------------------------------------------------------------------------------

NOT_RUN = "not run yet"
ON_RECORD = "seeds on record"   # the end of a part's reason while seeds are still to run
UNMATCHED = "its mixture start did not match plain BC"


class Part(NamedTuple):
    """One part's word on one task: ``ok`` True (passes), False (fails) or None (undecided),
    ``why`` the reason in words, and, for an undecided part, ``open``: True while seeds still
    to run (or not yet run) can decide it, False when none can (a start that is not weak, a
    mixture start that never matched): the part is then *not informative*; ``by_reference``
    True for a failure the standard library's run matches, which passes (:func:`judge_part`).
    Said where the reason is made, so that no caller reads the state back out of the words."""
    ok: bool | None
    why: str
    open: bool = True
    by_reference: bool = False


def judge_starts(observations: list[dict]) -> list[dict]:
    """The observations with each mixture variant's keep-part ``matched`` decided by the
    gate: its match record matched (``match_record``, on the match episodes) and its start
    scored, on the gate's own evaluation episodes, within :data:`KEEP_TOLERANCE` of the same
    seed's Gaussian start (its learner's cell; where that is not on record, the record
    alone decides)."""
    plain = {(o["row"], o["part"], o["task"], o.get("seed")): o["start"] for o in observations
             if o["row"] in VARIANTS.values()}
    out = []
    for o in observations:
        rec = o.get("match_record")
        if o["row"] in VARIANTS and rec is not None:
            base = plain.get((VARIANTS[o["row"]], o["part"], o["task"], o.get("seed")))
            o = dict(o, matched=bool(rec and (base is None
                                              or o["start"] >= base - KEEP_TOLERANCE)))
        out.append(o)
    return out


def knife_edge(shares: list[dict] | None) -> frozenset[str]:
    """The tasks whose starts are knife-edge by the ``start_noise`` study's ``shares`` (its
    aggregate's rows ``{"task", "scale", "share"}``): more than :data:`KNIFE_EDGE_SHARE` of
    the perturbed copies fall at :data:`STEP_SCALE`.  None (no record): no task."""
    return frozenset(r["task"] for r in shares or ()
                     if np.isclose(r["scale"], STEP_SCALE) and r["share"] > KNIFE_EDGE_SHARE)


def stored_knife_edge() -> frozenset[str]:
    """:func:`knife_edge` of the stored ``start_noise.json`` (no task while it is not made)."""
    try:
        rec = _storage.read_result(NOISE_RESULT)
    except FileNotFoundError:
        return frozenset()
    return knife_edge(rec.get("shares"))


DIP_NOT_GATED = "its dips are shown, not gated: the start is knife-edge"


# A standard library beside ours (issue 38, item 2): where our learner fails a part, is the
# failure our implementation's or the algorithm's at this budget?  A part our learner fails
# counts as *matched by the reference* when a standard library's implementation of the same
# algorithm (``perf.imitation_gail``: imitation 1.0.1's GAIL at its own tuned settings), run
# from the very same starts for the same interactions and scored by our evaluation, does no
# better: on at least ``REFERENCE_MIN_SEEDS`` seeds paired with ours, the 95% t interval of
# (ours - reference) final scaled return lies above ``-REFERENCE_MARGIN`` (the book's
# smallest effect).  Then the shortfall is the algorithm's at this budget, not our code's,
# and the gate lets the learner judge, saying so.  Decided after one reference seed of GAIL's
# hopper learn part (imitation 0.04 -> 0.15, ours 0.53), before the other reference seeds.
REFERENCES = {"gail": "imitation_gail"}
REFERENCE_MIN_SEEDS = 3
REFERENCE_MARGIN = 0.05


def reference_records(learner: str, part: str, task: str) -> list[dict]:
    """The stored reference result files of ``learner``'s algorithm on ``part`` and ``task``
    (``STEM_TASK.json`` or ``STEM_TASK_PART.json`` whose own ``part`` and ``task`` agree)."""
    stem, out = REFERENCES.get(learner), []
    for name in ((f"{stem}_{task}.json", f"{stem}_{task}_{part}.json") if stem else ()):
        try:
            rec = _storage.read_result(name)
        except FileNotFoundError:
            continue
        if rec.get("part") == part and rec.get("task") == task:
            out.append(rec)
    return out


def reference_rows(learner: str, part: str, task: str) -> list[dict]:
    """The stored reference runs of ``learner``'s algorithm on ``part`` and ``task`` (rows of
    ``seed``, ``start``, ``final``), [] where none is stored."""
    return [{"seed": r["seed"], "start": r["start"], "final": r["final"]}
            for rec in reference_records(learner, part, task) for r in rec.get("rows", ())]


def matches_reference(ours: list[dict], reference: list[dict]) -> tuple[bool, str]:
    """Whether our runs (with ``seed``) do at least as well as the reference's on the seeds
    both ran (:data:`REFERENCE_MIN_SEEDS` at least), and the evidence in words."""
    from dc_lesson.experiments import verdicts as _verdicts   # lazy: verdicts is a level up
    ref = {r["seed"]: r for r in reference}
    pairs = [(o["final"], ref[o["seed"]]["final"]) for o in ours if o.get("seed") in ref]
    if len(pairs) < REFERENCE_MIN_SEEDS:
        return False, (f"the reference ran {len(pairs)} of our seeds (needs "
                       f"{REFERENCE_MIN_SEEDS})")
    t = _verdicts.paired_t([a - b for a, b in pairs])
    said = (f"ours minus the reference {t.mean:+.2f} [{t.lo:+.2f}, {t.hi:+.2f}] on "
            f"{len(pairs)} paired seeds (reference mean {np.mean([b for _, b in pairs]):.2f})")
    return bool(t.lo > -REFERENCE_MARGIN), said


def stored_references(observations: list[dict]) -> dict:
    """``{(learner, part, task): (matched, evidence)}`` for every part with a stored reference."""
    out = {}
    for learner in REFERENCES:
        for part, tasks in (("keep", KEEP_TASKS), ("learn", LEARN_TASKS)):
            for task in tasks:
                ref = reference_rows(learner, part, task)
                if ref:
                    ours = [o for o in observations if o["row"] == learner
                            and o["part"] == part and o["task"] == task]
                    out[(learner, part, task)] = matches_reference(ours, ref)
    return out


def keeps(runs: list[dict], gate_dip: bool = True) -> Part:
    """``runs``: one task's seeds, each ``{"start", "final", "curve"}`` scaled returns (curve:
    a list of them). Whether the learner kept its perfect start there, and why not; None
    while no seed has run (not shown is not failed).  ``gate_dip=False`` on a knife-edge
    task (:func:`knife_edge`): the finals rule alone decides, and a pass says so."""
    if not runs:
        return Part(None, NOT_RUN)
    if any(r.get("matched") is False for r in runs):   # a mixture variant (VARIANTS)
        return so_far("keep", runs, len(runs), gate_dip)
    kept = [r["final"] >= r["start"] - KEEP_TOLERANCE for r in runs]
    dips = [r["start"] - min(r["curve"] or [r["final"]]) for r in runs]
    if np.mean(kept) < KEEP_SHARE:
        return Part(False, f"ended more than {KEEP_TOLERANCE} below its start on "
                           f"{len(runs) - sum(kept)} of {len(runs)} seeds")
    if not gate_dip:
        return Part(True, DIP_NOT_GATED)
    if max(dips) > MAX_DIP:
        return Part(False, f"a checkpoint fell {max(dips):.2f} below its start")
    return Part(True, "")


def learns(runs: list[dict]) -> Part:
    """One task's seeds from the weak start: True / False, or None when the start was not
    weak (the question then tells nothing) or while no seed has run."""
    if not runs:
        return Part(None, NOT_RUN)
    start = float(np.mean([r["start"] for r in runs]))
    if start > WEAK_CEILING:   # more seeds of the same start would not make it weak
        return Part(None, f"its weak start was not weak ({start:.2f} > {WEAK_CEILING})", False)
    final = float(np.mean([r["final"] for r in runs]))
    if final < LEARN_FLOOR:
        return Part(False, f"reached {final:.2f} from {start:.2f} (needs {LEARN_FLOOR})")
    return Part(True, "")


def so_far(part: str, runs: list[dict], n_seeds: int, gate_dip: bool = True) -> Part:
    """A part while fewer than its ``n_seeds`` seeds are on record: failed only where no seed
    still to come can change the word (a gated dip, or more seeds ended below their start than
    :data:`KEEP_SHARE` of ``n_seeds`` allows), else None: a pass or a shortfall on some of
    the seeds is not yet the study's (one failed seed in three is within the keep rule's
    allowance of ten; a learn mean moves with every seed)."""
    have = f"{len(runs)} of {n_seeds} {ON_RECORD}"
    unmatched = sum(r.get("matched") is False for r in runs)
    runs_all, runs = runs, [r for r in runs if r.get("matched") is not False]
    if part == "keep" and runs:   # the seeds whose start is the keep question's
        ended = sum(r["final"] < r["start"] - KEEP_TOLERANCE for r in runs)
        allowed = n_seeds - math.ceil(KEEP_SHARE * n_seeds - 1e-9)
        if ended > allowed:
            return Part(False, f"ended more than {KEEP_TOLERANCE} below its start on {ended} "
                               f"of {have} (the rule allows {allowed} of {n_seeds})")
        dip = max(r["start"] - min(r["curve"] or [r["final"]]) for r in runs)
        if gate_dip and dip > MAX_DIP:
            # the table's worst fall is over every seed: say this one is a matched seed's
            whose = " of a seed whose start matched" if unmatched else ""
            return Part(False, f"a checkpoint{whose} fell {dip:.2f} below its start")
    if part == "keep" and unmatched:   # final: no seed to come makes a start perfect
        return Part(None, f"{UNMATCHED} on {unmatched} of {len(runs_all)} seeds: a start "
                          f"that is not perfect cannot be kept", False)
    return Part(None, have if runs_all else NOT_RUN)


def judge_part(part: str, task: str, runs: list[dict],
               knife: frozenset[str] = frozenset(),
               reference: tuple[bool, str] | None = None,
               n_seeds: int | None = None) -> Part:
    """One part on one task: :func:`keeps` (its dip gated unless ``task`` is in ``knife``)
    or :func:`learns`; a failure that ``reference`` (:func:`matches_reference`) matches
    passes (``by_reference``), with its failure and the reference's evidence as its reason.
    ``n_seeds``: the study's seeds for the part; with fewer on record the word is
    :func:`so_far`'s (None: every run on record is taken as the whole part)."""
    if n_seeds is not None and len(runs) < n_seeds:
        word = so_far(part, runs, n_seeds, gate_dip=task not in knife)
    else:
        word = (keeps(runs, gate_dip=task not in knife) if part == "keep"
                else learns(runs))
    if word.ok is False and reference is not None and reference[0]:
        return Part(True, f"{word.why}; {reference[1]}", by_reference=True)
    return word


def part_seeds(b) -> dict[str, int]:
    """The study's seeds per part at budget ``b``: what a part needs on record to be decided."""
    return {"keep": b.competence_keep_seeds, "learn": b.competence_learn_seeds}


def budget_seeds(aggregate: dict) -> dict[str, int] | None:
    """:func:`part_seeds` of the budget an aggregate's cells ran at (None: not recorded)."""
    name = aggregate.get("budget")
    return part_seeds(_budget.get(name)) if name else None


def gate(observations: list[dict], knife: frozenset[str] = frozenset(),
         references: dict | None = None,
         seeds: dict[str, int] | None = None) -> dict[str, dict]:
    """Per learner: ``{"passed": bool | None, "reason": str}`` from the aggregate's
    observations.  False when a part on record fails (the reason names the failing parts),
    None when none fails but a part is not run, not informative or not yet run on all its
    seeds (the reason names those; ``"open"`` says whether a part is still to run or decide:
    False when only a not-informative part, which no seed to come changes, holds it back),
    True when every part passes.  ``knife``: the knife-edge
    tasks, whose dips are not gated; ``references``: :func:`stored_references`' mapping, a
    failure it matches passes; ``seeds``: :func:`part_seeds`, the seeds a part needs before
    it is decided (None: the seeds on record are the whole part)."""
    references = references or {}
    observations = judge_starts(observations)
    out = {}
    for learner in LEARNERS:
        words: list[Part] = []
        for part, tasks in (("keep", KEEP_TASKS), ("learn", LEARN_TASKS)):
            for task in tasks:
                runs = [{"start": o["start"], "final": o["final"], "curve": o["curve"],
                         "matched": o.get("matched")}
                        for o in observations if o["row"] == learner and o["part"] == part
                        and o["task"] == task]
                word = judge_part(part, task, runs, knife,
                                  references.get((learner, part, task)),
                                  (seeds or {}).get(part))
                words.append(word._replace(why=f"{part} on {task}: {word.why}"))
        oks = [w.ok for w in words]
        passed = (False if False in oks else None if None in oks else True)
        out[learner] = {"passed": passed,
                        "reason": "; ".join(w.why for w in words if w.ok is passed
                                            and passed is not True)}
        if passed is None:   # open: a part still to run or decide; else none can decide it
            out[learner]["open"] = any(w.ok is None and w.open for w in words)
    return out


def competence(aggregate: dict, knife: frozenset[str] = frozenset(),
               references: dict | None = None) -> dict[str, str]:
    """The ``competence`` mapping for :mod:`dc_lesson.experiments.verdicts`: each learner that
    did not pass, with the phrase a "not judged" verdict prints after its name.  The gate is
    recomputed from the observations by today's rules (``knife``: the knife-edge tasks), so
    a rule changed since the aggregate was written reaches every verdict."""
    g = (gate(aggregate["observations"], knife, references, budget_seeds(aggregate))
         if "observations" in aggregate else aggregate["gate"])
    out = {k: (f"failed the competence gate — {v['reason']}" if v["passed"] is False
               else f"has not yet shown competence — {v['reason']}" if v.get("open", True)
               else f"cannot show competence on our ports — {v['reason']}")
           for k, v in g.items() if v["passed"] is not True}
    # a variant that passed is named with no phrase, so that a verdict on its rows stops at
    # it instead of reading its learner's word (verdicts.rows_gate)
    out.update({k: "" for k in VARIANTS if g.get(k, {}).get("passed") is True})
    return out


def aggregate(records, b) -> dict:
    obs = []
    for r in records:
        cell, res = r["cell"], r["result"]
        obs.append({"row": cell["learner"], "task": cell["task"], "seed": cell["seed"],
                    "part": cell["variant"], "start": res["start"]["scaled_return"],
                    "final": res["final"]["scaled_return"],
                    "curve": [p["scaled_return"] for p in res["curve"]],
                    "curve_steps": [p["steps"] for p in res["curve"]],
                    "match_record": res["match"]["matched"] if "match" in res else None,
                    # wall-clock figures live in the record's timing (cells.split_timing)
                    "train_seconds": r.get("timing", {}).get("train_seconds")})
    knife = stored_knife_edge()
    rules = {"keep_tolerance": KEEP_TOLERANCE, "keep_share": KEEP_SHARE, "max_dip": MAX_DIP,
             "learn_floor": LEARN_FLOOR, "weak_ceiling": WEAK_CEILING,
             "step_scale": STEP_SCALE, "knife_edge_share": KNIFE_EDGE_SHARE,
             "dip_not_gated_on": sorted(knife), "reference_min_seeds": REFERENCE_MIN_SEEDS,
             "reference_margin": REFERENCE_MARGIN}
    return {"gate": gate(obs, knife, stored_references(obs), part_seeds(b)), "rules": rules,
            "steps": {"keep": b.competence_keep_steps, "learn": b.competence_learn_steps},
            "observations": obs}


STUDY = cells.Study(NAME, "every RL learner keeps a perfect start and learns from a weak one",
                    cells=cells_at, run_cell=run_cell, aggregate=aggregate,
                    result_file="competence.json")

__all__ = ["DIP_NOT_GATED", "KEEP_TASKS", "KNIFE_EDGE_SHARE", "LEARNERS", "LEARN_TASKS", "NAME",
           "ON_RECORD", "Part", "UNMATCHED", "VARIANTS", "algorithm", "judge_starts",
           "mixture_start",
           "STEP_SCALE", "STUDY", "aggregate", "budget_seeds", "cells_at", "competence", "gate",
           "judge_part", "part_seeds", "so_far",
           "keeps", "knife_edge", "learns", "matches_reference", "reference_records",
           "reference_rows", "run_cell",
           "stored_knife_edge", "stored_references"]
