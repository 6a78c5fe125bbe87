"""The paper's Table I in full, as cells (chapter 04; ``table1.json``): every learner and control
on the multi-mode tasks, evaluated with the mean action and with sampled actions.

Cells: per task of ``reacher4, reacher2, halfcheetah2``, seed of ``budget.seeds_for(task)`` and
row of :data:`ROWS`, one run on the first ``il_demos`` demonstrations (the realizable experts'
by default, the hidden-coin experts' for the ``*coin`` rows) with ``il_steps`` interactions;
and the expert row.  A learner that starts from BC trains the seed's warm start itself (the
same policy in every cell of that seed and demonstration set, so rows pair by seed) and
evaluates it beside its final policy, both ways, on the same fresh episodes.

The rows (``ROWS``; stage = the order a sweep runs them in, so an interrupted grid has the
core comparison first):

======================  =====  ==============================================================
row                     stage  what it is
======================  =====  ==============================================================
``bc`` (start)                 the 70/30 BC warm start of every RL row (the paper's BC)
``bc-all``              1      BC on all 18 demonstrations, early stopping on the task's 7
                               other expert episodes (what the RL rows see, no less)
``bc-full``             1      BC on all 18 trained to a fixed budget (200 epochs of 64
                               pairs, the last kept), as the imitation library trains it:
                               on 3 reacher4 seeds it beat bc-all; the row tests that
``bc-lib``              1      BC on all 18 as imitation 1.0.1 trains it (the standard-library
                               baseline): a 32-32 tanh MLP, no observation normaliser, 50,000
                               minibatches of 32 (89 epochs of 18,000 pairs), the last kept
``gail``, ``dc``        1      GAIL (D(s, a); its start's log-std set to -2, the one knob
                               tuned, ``gail.GAILConfig.start_log_std``) and DC
                               (``reward="scaled"``) from the start
``dc-noppo``            2      DC with its PPO step off: BC continuation, same optimiser steps
``dc-raw``              2      DC with the paper's raw reward log P_w(s')
``dc-gailreward``       2      Algorithm 2 with GAIL's -log(1 - D(s')) in place of log P_w
``gail-state``          2      GAIL with a state-only D(s): action noise cannot give it away
``gail-noisy``          2      GAIL exploring with the warm start's log-std -0.5 (untuned)
``dril`` ... ``gpril``  3      the paper's other baselines, from the same start
``bc-mix``, ``dc-mix``  4      the mixture policy (4 components): BC as bc-full, DC from it
``dc-coin`` ...         4      the hidden-coin demonstrations: DC, mixture BC and DC
``bc-full-coin``        4      the Gaussian BC trained as bc-mix-coin is (all 18, fixed
                               budget), on the mixture rows' seeds: the matched control
                               that asks what the mixture itself changes on the coin
``gail-coin``           5      GAIL on the hidden-coin demonstrations, from the same coin BC
                               start as dc-coin: chapter 02's coin-flip experiment as cells,
                               with the seeds of the rest of the table
======================  =====  ==============================================================

Choices: the mixture rows run on the first ``budget.table1_mixture_seeds`` seeds (5 at
``lesson``: the fewest a paired verdict accepts; they cost two to three times a Gaussian row);
the mixture DC starts from the mixture BC with its component spreads reset to
e^-0.5 (state-independent), as the Gaussian warm start's log-std is reset, so PPO explores;
the expert row is evaluated once (its mean action is its behaviour).

Its mixture rows ran with the mixture's spread floor at e^-5
(``nn.mixture.FIRST_GRID_LOG_STD_MIN``); the library's floor is now e^-2 (``nn.mixture``
says why), so a mixture cell of this study run today would not repeat its stored numbers.
The study is superseded by ``modes`` (``studies.SUPERSEDED``) and its stored cells stay the
record of what ran.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import time

import torch

from dc_lesson import algorithms as _algorithms
from dc_lesson import evaluation as _evaluation
from dc_lesson.algorithms import bc as _bc
from dc_lesson.data import store as _store
from dc_lesson.evaluation import stats as _stats
from dc_lesson.experiments import cells
from dc_lesson.experiments.studies import _common, _imitation as _im

NAME = "table1"
N_COMPONENTS = 4


@dataclasses.dataclass(frozen=True)
class Row:
    learner: str
    variant: str
    stage: int
    overrides: tuple = ()        # (field, value) pairs of the learner's config
    demos: str = ""              # "" (realizable experts) or "coin"
    mixture: bool = False        # the mixture policy (BC's, or DC from BC's)
    mixture_seeds: bool = False  # a control of the mixture rows: runs on their seeds only

    @property
    def evaluates_start(self) -> bool:
        """Whether the cell evaluates its start: the rows that own a start kind (GAIL and DC
        for the Gaussian start on the realizable demonstrations; the mixture and coin rows
        for theirs).  The start is the same policy in every cell of a seed, so the controls
        and baselines skip its four evaluations (a fifth of a cell's time) and pair with the
        start the core rows measured."""
        return self.stage == 1 or self.mixture or bool(self.demos)

    @property
    def name(self) -> str:
        return self.learner + (f"-{self.variant}" if self.variant else "")


ROWS = {r.name: r for r in (
    Row("bc", "all", 1),
    Row("bc", "full", 1),
    Row("bc", "lib", 1),
    Row("gail", "", 1),
    Row("dc", "", 1),
    Row("dc", "noppo", 2, (("ppo_step", False),)),
    Row("dc", "raw", 2, (("reward", "raw"),)),
    Row("dc", "gailreward", 2, (("reward", "gail"),)),
    Row("gail", "state", 2, (("disc_actions", False),)),
    Row("gail", "noisy", 2, (("start_log_std", _bc.WARM_START_LOG_STD),)),
    Row("dril", "", 3), Row("pwil", "", 3), Row("ndi", "", 3), Row("gpril", "", 3),
    Row("bc", "mix", 4, mixture=True),
    Row("dc", "mix", 4, mixture=True),
    Row("dc", "coin", 4, demos="coin"),
    Row("bc", "mix-coin", 4, demos="coin", mixture=True),
    Row("dc", "mix-coin", 4, demos="coin", mixture=True),
    Row("bc", "full-coin", 4, demos="coin", mixture_seeds=True),
    Row("gail", "coin", 5, demos="coin"),
)}


FULL_BATCH = 64   # bc-full's minibatch: 200 epochs of 64 pairs, about 56,000 steps on 18 demos


def _bc_config(b, seed: int, mixture: bool, full: bool = False) -> _bc.BCConfig:
    """BC on all the demonstrations: early stopping on the task's other expert episodes
    (``bc-all``), or (``full``: ``bc-full`` and the mixture rows) no early stopping, the
    budget's epochs of minibatches of FULL_BATCH, the last epoch kept."""
    if full:
        return _bc.BCConfig(epochs=b.bc_max_epochs, batch_size=FULL_BATCH, val_fraction=0.0,
                            policy="mixture" if mixture else "gaussian",
                            n_components=N_COMPONENTS, seed=seed)
    return _bc.BCConfig(epochs=b.bc_max_epochs, val_fraction=0.0, stop_on_others=True,
                        policy="mixture" if mixture else "gaussian",
                        n_components=N_COMPONENTS, seed=seed)


def learner_config(row: Row, b, seed: int):
    """The row's learner config at budget ``b`` (the budget's interactions)."""
    if row.name == "bc-lib":
        return _bc.library_recipe(seed)
    if row.learner == "bc":
        return _bc_config(b, seed, row.mixture, full=row.variant != "all")
    algo = _algorithms.get(row.learner)
    if row.learner == "dc":
        return algo.preset(b, seed, **dict(row.overrides))
    cfg = algo.preset(b, seed)
    return dataclasses.replace(cfg, **dict(row.overrides)) if row.overrides else cfg


def _config_json(cfg) -> dict:
    return _im.without_seed(json.loads(cfg.to_json()))


def _cell(row: Row, task: str, seed: int, b) -> cells.Cell:
    extra = {} if row.learner == "bc" or row.evaluates_start else {"evaluate_start": False}
    c = _im.learner_cell(NAME, row.learner, task, seed, b,
                         _config_json(learner_config(row, b, seed)), variant=row.variant,
                         demo_variant=row.demos or None, mixture=row.mixture, **extra)
    return dataclasses.replace(c, stage=row.stage)


def seeds(row: Row, task: str, b) -> tuple[int, ...]:
    """The row's seeds on ``task``: the budget's, or its first ``table1_mixture_seeds`` for
    the mixture rows (``budget.Budget.table1_mixture_seeds`` says why)."""
    all_seeds = b.seeds_for(task)
    return (all_seeds[:b.table1_mixture_seeds] if row.mixture or row.mixture_seeds
            else all_seeds)


def cells_at(b) -> list[cells.Cell]:
    """The expert row first, then seed-major within a stage: an interrupted stage has every
    row at its first seeds."""
    rows = sorted(ROWS.values(), key=lambda r: r.stage)
    learners = [_cell(r, t, s, b) for r in rows for t in _im.TASKS for s in seeds(r, t, b)]
    learners.sort(key=lambda c: (c.stage, c.seed, _im.TASKS.index(c.task)))
    return _im.expert_rows(NAME, _im.TASKS, b) + learners   # the floor first: it is cheap


def _mixture_start(policy, log_std: float = _bc.WARM_START_LOG_STD):
    """The mixture BC as a start for RL: each component's log-std set to ``log_std`` (the
    Gaussian warm start's here; the gate's in ``modes``), state-independent, means and
    weights untouched."""
    policy = copy.deepcopy(policy)
    k, a = policy.k, policy.act_dim
    with torch.no_grad():
        policy.head.weight[k + k * a:].zero_()
        policy.head.bias[k + k * a:].fill_(float(log_std))
    return policy


def _start(task, demos, variant, seed: int, b, c, mixture: bool):
    """The seed's BC start (cached per worker: :func:`_imitation.cached_start`)."""
    key = (task, len(demos.trajectories), variant, seed, c["bc_max_epochs"], mixture)
    if mixture:
        return _im.cached_start(key, lambda: _mixture_start(_bc.train(
            task, demos, _bc_config(b, seed, True, full=True), progress=False).policy))
    return _im.cached_start(key, lambda: _bc.warm_start_policy(
        demos, seed, max_epochs=c["bc_max_epochs"]))


def _evaluate(task, policy, reference, c, seed):
    both = _evaluation.evaluate_both(task, policy, reference, n_episodes=c["eval_episodes"],
                                     seed=c["eval_seed"], keep_features=True)
    feats = both["mean"].pop("features")
    both["sampled"].pop("features")
    return ({a: {k: ev[k] for k in _im.protocol.MEASURED} for a, ev in both.items()},
            _common.features({"mean": feats}, seed)["mean"])


def run_cell(cell, needs):
    """One row's run: its demonstrations, its start, the learner, both evaluated both ways."""
    c = cell.config
    row = ROWS[cell.row]
    b = _im.sized_budget(c)
    cfg = learner_config(row, b, cell.seed)
    _im.check_config(cell, json.loads(cfg.to_json()))
    reference = _common.reference(needs)
    variant = c["demo_variant"]
    demos = _store.load_demos(cell.task, n_trajectories=c["n_demos"], variant=variant)
    t0 = time.perf_counter()
    out, feats = {}, {}
    if row.learner == "bc":
        result = _bc.train(cell.task, demos, cfg, progress=False)
    else:
        start = _start(cell.task, demos, variant, cell.seed, b, c, row.mixture)
        if c.get("evaluate_start", True):
            t_start = time.perf_counter()
            out["start"], feats["start"] = _evaluate(cell.task, start, reference, c, cell.seed)
            out["start_seconds"] = time.perf_counter() - t_start
        t0 = time.perf_counter()
        result = _algorithms.get(row.learner).train(cell.task, demos, cfg,
                                                    policy=copy.deepcopy(start), progress=False)
    out["train_seconds"] = time.perf_counter() - t0
    out["final"], feats["final"] = _evaluate(cell.task, result.policy, reference, c, cell.seed)
    out["curve"] = _curve(result.log)
    last = result.log[-max(1, len(result.log) // 10):]
    out["log_final"] = {k: _common.finite(sum(r[k] for r in last) / len(last))
                        for k in last[0] if all(isinstance(r.get(k), (int, float))
                                                and not isinstance(r.get(k), bool)
                                                for r in last)} if last else {}
    return out, feats


CURVE_KEYS = ("env_steps", "steps", "episode_return", "param_change_l1", "pi_pi_prime_l1",
              "reward_mean", "loop")


def _curve(log) -> dict:
    """The training log's learning-curve columns (iterations only; a flow row has none)."""
    rows = [r for r in log if r.get("kind", "iteration") == "iteration"]
    return {k: [_common.finite(r.get(k)) for r in rows] for k in CURVE_KEYS
            if rows and any(k in r for r in rows)}


# -- the aggregate ----------------------------------------------------------------------------

ACTIONS = ("mean", "sampled")


def observations(records, actions: str) -> list[dict]:
    """One observation per policy a cell evaluated with ``actions``: the start of an RL row
    becomes row ``bc`` (the 70/30 warm start; ``bc-coin`` on the coin demonstrations,
    ``bc-mixstart`` for the mixture's reset start), kept once per (task, seed, start)."""
    from dc_lesson.experiments import aggregate as _agg
    obs, seen = [], set()
    for r in records:
        res = r["result"]
        if "measures" in res:      # the expert row: one evaluation, its mean action
            obs.append(_agg.observation(r, res["measures"]))
            continue
        row = ROWS[r["cell"]["learner"] + (f"-{r['cell']['variant']}"
                                            if r["cell"]["variant"] else "")]
        if "start" in res:
            start = ("bc-mixstart" if row.mixture else "bc") + ("-coin" if row.demos else "")
            key = (r["cell"]["task"], r["cell"]["seed"], start)
            if key not in seen:
                seen.add(key)
                obs.append(_agg.observation(r, res["start"][actions], row=start))
        extra = {"curve": res.get("curve")}
        if row.learner == "dc":   # iterations per loop: the convergence claim's unit
            extra["iterations"] = r["config"]["dc"]["iterations"]
        obs.append(_agg.observation(r, res["final"][actions], **extra))
    return obs


PAIRS = (("dc", "bc"), ("dc", "gail"), ("dc", "bc-all"), ("dc", "bc-full"), ("gail", "bc"),
         ("bc-all", "bc"), ("bc-full", "bc-all"), ("bc-lib", "bc-full"), ("dc", "bc-lib"),
         ("gail", "bc-lib"),
         ("dc", "dc-noppo"), ("dc", "dc-raw"), ("dc", "dc-gailreward"), ("gail", "gail-state"),
         ("gail", "gail-noisy"),
         ("dc", "dril"), ("dc", "pwil"), ("dc", "ndi"), ("dc", "gpril"),
         # each baseline against the BC start it shares with DC and GAIL (chapter 05)
         ("dril", "bc"), ("pwil", "bc"), ("ndi", "bc"), ("gpril", "bc"),
         ("bc-mix", "bc-full"), ("dc-mix", "dc"), ("dc-coin", "bc-coin"),
         ("bc-mix-coin", "bc-coin"), ("dc-mix-coin", "dc-coin"), ("gail-coin", "bc-coin"),
         ("dc-coin", "gail-coin"),
         # the mixture's matched controls: same training, Gaussian against mixture; and each
         # mixture DC against its own start
         ("bc-mix-coin", "bc-full-coin"), ("bc-full-coin", "bc-coin"),
         ("dc-mix", "bc-mixstart"), ("dc-mix-coin", "bc-mixstart-coin"))


def both_evaluations(records, observe, pairs, eval_episodes: int,
                     actions: tuple = ACTIONS) -> dict:
    """Per evaluation of ``actions`` (:data:`ACTIONS`; ``modes`` adds ``"components"``): the
    table, the expert row, the paired differences of ``pairs`` (the aggregate's measures and the TV of a seed's mode shares from the
    reference's: the mode question's own measure, per seed so that it pairs), the mode
    summary and the observations ``observe(records, actions)`` gives (this study's and
    ``modes``'; a run's training ``curve`` only in the mean action's, which
    ``table_one.curves`` reads)."""
    from dc_lesson.experiments import aggregate as _agg
    shares = _im.reference_shares(records)
    out, kinds = {}, actions
    for actions in kinds:
        obs = observe(records, actions)   # the expert row: its one evaluation in both
        if actions != "mean":   # a run's training curve is one, whatever the evaluation:
            obs = [{k: v for k, v in o.items() if k != "curve"} for o in obs]   # kept once
        for o in obs:
            ref = shares.get(o["task"])
            o["mode_tv"] = _stats.tv(ref, o["mode_shares"]) if ref and o.get(
                "mode_shares") else None
        out[actions] = {
            "table": _agg.table([o for o in obs if o["row"] != "expert"]),
            "expert": _agg.table([o for o in obs if o["row"] == "expert"]),
            "paired": [p for a, bb in pairs for p in _agg.paired(
                obs, a, bb, measures=(*_agg.MEASURES, "mode_tv"))],
            "modes": _im.mode_summary(obs, shares, eval_episodes),
            "observations": obs}
    return out


def aggregate(records, b) -> dict:
    out = {"interval": "95% bootstrap (BCa) over seeds; paired: of the per-seed differences",
           "protocol": _im.protocol_config(b), "rows": {k: dataclasses.asdict(v)
                                                        for k, v in ROWS.items()}}
    eval_episodes = records[0]["config"].get("eval_episodes", b.il_eval_episodes)
    out.update(both_evaluations(records, observations, PAIRS, eval_episodes))
    return out


STUDY = cells.Study(NAME, "Table I: every learner and control on the multi-mode tasks",
                    cells=cells_at,
                    run_cell=lambda c, n: _common.run_expert_or(c, n, run_cell),
                    aggregate=aggregate, result_file="table1.json")
