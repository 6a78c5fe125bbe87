"""Our BC against a standard library's: ``python -m dc_lesson.perf.imitation_ref --out FILE``.

Trains HumanCompatibleAI imitation 1.0.1's BC on our demonstrations (the task's first
``n_demos``), at that library's own training-script defaults (its ``FeedForward32Policy``:
a 32-32 tanh MLP, no observation normaliser, Adam at 1e-3, 50,000 minibatches of 32, entropy
weight 1e-3), copies its weights into our :class:`~dc_lesson.nn.policies.GaussianPolicy`
(same layers, same activation: the mean action is the same function), and scores it with our
own :func:`~dc_lesson.evaluation.evaluate_policy` (mean action, 50 episodes from the evaluation
seed; its EMD is to the demonstrations trained on).  Beside it, our BC with the same recipe (``table1``'s ``bc-lib`` row)
on seeds of the same numbers, so one command gives both; the two libraries draw different
random numbers from a seed, so the seeds are not paired.

imitation is not a dependency of dc_lesson (it pins gymnasium 0.29.1, stable-baselines3 2.2.1
and an older shimmy): install it in its own environment that sees this one's packages,
``python -m venv --system-site-packages VENV && VENV/bin/pip install imitation==1.0.1
torch==2.13.0 mujoco==3.17.0 dm-control==1.0.50``, and run this module with ``VENV/bin/python``.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np
import torch

from dc_lesson import data
from dc_lesson.algorithms import bc
from dc_lesson.evaluation import evaluate_policy
from dc_lesson.nn import fast
from dc_lesson.nn.policies import GaussianPolicy
from dc_lesson.storage import check_writable, write_result

N_BATCHES, BATCH, HIDDEN = 50_000, 32, (32, 32)
# imitation's ActorCriticPolicy names -> ours (the value network is not used by BC)
LAYERS = {"mean_net.0.weight": "mlp_extractor.policy_net.0.weight",
          "mean_net.0.bias": "mlp_extractor.policy_net.0.bias",
          "mean_net.2.weight": "mlp_extractor.policy_net.2.weight",
          "mean_net.2.bias": "mlp_extractor.policy_net.2.bias",
          "mean_net.4.weight": "action_net.weight", "mean_net.4.bias": "action_net.bias",
          "log_std": "log_std"}


def _imitation():
    try:
        import gymnasium
        from imitation.algorithms import bc as im_bc
        from imitation.data.types import Transitions
        from imitation.util import logger
    except ImportError:
        raise ImportError("this benchmark needs imitation 1.0.1 in its own environment (see "
                          "`python -m dc_lesson.perf.imitation_ref --help`)") from None
    return gymnasium, im_bc, Transitions, logger


def imitation_bc(demos, seed: int, n_batches: int = N_BATCHES) -> GaussianPolicy:
    """imitation's BC on ``demos`` with ``seed``, as our GaussianPolicy."""
    gym, im_bc, Transitions, logger = _imitation()
    obs = np.concatenate([t.observations[:-1] for t in demos.trajectories]).astype(np.float32)
    nxt = np.concatenate([t.observations[1:] for t in demos.trajectories]).astype(np.float32)
    act = np.concatenate([t.actions for t in demos.trajectories]).astype(np.float32)
    pairs = Transitions(obs=obs, acts=act, infos=np.array([{}] * len(obs)), next_obs=nxt,
                        dones=np.zeros(len(obs), bool))
    torch.manual_seed(seed)   # imitation builds its policy from torch's global generator
    trainer = im_bc.BC(observation_space=gym.spaces.Box(-np.inf, np.inf, obs.shape[1:],
                                                        np.float32),
                       action_space=gym.spaces.Box(-1.0, 1.0, act.shape[1:], np.float32),
                       demonstrations=pairs, rng=np.random.default_rng(seed), batch_size=BATCH,
                       custom_logger=logger.configure(format_strs=[]))   # no tables on stdout
    trainer.train(n_batches=n_batches, progress_bar=False, log_interval=10 ** 9)
    theirs = trainer.policy.state_dict()
    policy = GaussianPolicy(obs.shape[1], act.shape[1], HIDDEN, log_std_init=0.0)
    policy.load_state_dict({k: theirs[v].detach().clone() for k, v in LAYERS.items()})
    return policy


@fast.on()   # ours as sweep workers train it (dc_lesson.nn.fast)
def compare(task: str, seeds, n_demos: int = 18, n_episodes: int = 50,
            n_batches: int = N_BATCHES) -> dict:
    """Per seed: imitation's BC and ours (``bc-lib``'s recipe), scored alike."""
    demos = data.load_demos(task, n_trajectories=n_demos)
    rows = []
    for seed in seeds:
        for who in ("imitation", "ours"):
            t0 = time.perf_counter()
            if who == "imitation":
                policy = imitation_bc(demos, seed, n_batches)
            else:
                cfg = bc.library_recipe(int(seed))
                policy = bc.train(task, demos, cfg, progress=False).policy
            seconds = time.perf_counter() - t0
            ev = evaluate_policy(task, policy, demos, n_episodes=n_episodes)
            rows.append({"library": who, "seed": int(seed), "scaled_return": ev["scaled_return"],
                         "emd": ev["emd"], "train_seconds": seconds})
    return {"task": task, "n_demos": n_demos, "n_episodes": n_episodes, "n_batches": n_batches,
            "rows": rows}


def ready(out: str | None, check_import=None) -> None:
    """Before any compute: ``out`` writable, imitation importable (``check_import``, default
    this module's; else exit 2 with the fix, the first thing to say), one torch thread."""
    if out:
        check_writable(out)
    try:
        (check_import or _imitation)()
    except ImportError as e:
        print(f"error: {e}", file=sys.stderr)
        raise SystemExit(2) from None
    torch.set_num_threads(1)


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(prog="python -m dc_lesson.perf.imitation_ref",
                                description=__doc__.split("\n")[0])
    p.add_argument("--task", default="reacher4")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3])
    p.add_argument("--out", default=None, help="write the result JSON here")
    args = p.parse_args(argv)
    ready(args.out)
    out = compare(args.task, args.seeds)
    for r in out["rows"]:
        print(f"{r['library']:9s} seed {r['seed']}: scaled return {r['scaled_return']:.3f}, "
              f"EMD {r['emd']:.3f}")
    if args.out:
        write_result(args.out, {"benchmark": "imitation_reference", **out},
                     command="python -m dc_lesson.perf.imitation_ref "
                     + " ".join(argv or sys.argv[1:]), seeds=args.seeds)
    return out


if __name__ == "__main__":  # pragma: no cover
    main()
