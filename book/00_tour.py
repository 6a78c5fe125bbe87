# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#       jupytext_version: 1.19.6
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # 0. A tour of the tasks
#
# **Imitation learning** (IL) learns a policy from an expert's demonstrations, with no reward
# signal: we are shown what a competent agent does in the states it visits, and must act well
# in the states *we* visit. The paper this book follows, *Distributional Cloning for Stabilized
# Imitation Learning via ADMM* (DC), starts from the field's two paradigms.
#
# **Behaviour cloning (BC)** treats demonstrations as a supervised data set of (state, action)
# pairs and maximises the likelihood of the expert's actions, $\max_\pi \mathbb{E}_{(s,a)\in
# \mathcal{D}_E}[\log \pi(a\mid s)]$ (the paper's Eq. 1). It is simple and needs no interaction
# with the environment, but it only learns what to do in the expert's states: a small error
# takes the learner to states the expert never showed, where its errors grow. This is
# *covariate shift*, the subject of chapter 1.
#
# **Generative adversarial imitation learning (GAIL)** instead makes the learner's
# distribution of (state, action) pairs hard to tell from the expert's: a discriminator learns
# to separate them and its output is the learner's reward for reinforcement learning. Matching
# distributions fixes covariate shift, but the adversarial game is unstable and may settle on
# *one* of the expert's behaviours (*mode collapse*), the subject of chapter 2.
#
# **DC**, the paper's method, maximises the likelihood of expert *and* learner state-action
# pairs, split into a state density $P(s)$ fitted by a normalizing flow (SoftFlow, chapter 3)
# and a policy $\pi(a\mid s)$ trained by a BC step and a reinforcement-learning step with
# reward $\log P(s)$, whose parameters are averaged ("ADMM", chapter 4).
#
# This chapter meets the ten tasks every later chapter runs on: the paper's Gym tasks, ported
# to DeepMind's [dm_control](https://github.com/google-deepmind/dm_control) on MuJoCo.

# %%
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from dc_lesson import notebook, tasks
from dc_lesson.viz import plots, render
from dc_lesson.data import rollout
from dc_lesson.experiments import tour

BUDGET = notebook.start(
    "the random-policy returns below come from a few episodes per task and mean little; the "
    "experts, demonstrations, floors, learning curves and rollout speeds are read from stored "
    "results and are real.")

# %% [markdown]
# ## The ten ports
#
# Each port is a dm_control task in the suite's style: an XML model, a `Physics` class with
# named helpers (`physics.speed()`, `physics.fingertip()`), and a `Task` whose randomness comes
# only from its own `RandomState`. `tasks.make(name, seed)` builds one; its observations are
# flat `float32` vectors, every episode lasts exactly 1000 control steps, and each step's reward
# lies in $[0, 1]$, so a return is on a 0 to 1000 scale in every task.
#
# Each task also names a low-dimensional **mode feature**: where the fingertip is, how fast the
# body moves. Later chapters compare expert and learner *distributions* of this feature, in
# coverage plots and with the earth mover's distance and KL divergences.

# %%
table = pd.DataFrame(tasks.spec_table()).set_index("task")
table[["paper task", "dm_control base", "obs", "act", "horizon", "control dt (s)",
       "physics steps", "mode feature", "modes"]]

# %%
names = list(tasks.NAMES)
fig = plots.gallery(tour.frames(names, height=180, width=240), names)
plt.show()

# %% [markdown]
# ## Two tasks with several good behaviours
#
# Three ports exist to study **modes**: `reacher2` and `reacher4` reward the fingertip for
# being inside *any* of 2 or 4 fixed targets, and `halfcheetah2` rewards running speed in
# *either* direction. The targets and the direction are not in the observation, so which mode
# an episode takes is a property of the policy, not of the task. An expert that spreads its
# episodes over all modes is the test of whether an imitation learner keeps them all.
#
# Below, left: the `reacher4` arena seen from above with its four targets and where the
# fingertip of a random policy goes; right: the `halfcheetah2` reward as a function of the
# forward speed, read from the task itself (setting the velocity and asking for the reward).

# %%
from dc_lesson.tasks import reacher

random_trajs = rollout.collect("reacher4", rollout.RandomPolicy("reacher4", seed=0),
                               n_episodes=max(2, BUDGET.tour_episodes // 2), seed=0)
tips = np.concatenate([t.mode_features for t in random_trajs])

env = tasks.make("halfcheetah2", seed=0)
env.reset()
speeds = np.linspace(-14, 14, 57)
rewards_2 = []
for v in speeds:
    env.physics.data.qvel[0] = v          # the torso's forward velocity
    env.physics.forward()
    rewards_2.append(env.task.get_reward(env.physics))

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
ax1.plot(tips[:, 0], tips[:, 1], ".", ms=1, alpha=0.3, color="grey", label="random fingertip")
for xy, colour in zip(reacher.target_positions(4), reacher.target_colours(4)):
    ax1.add_patch(plt.Circle(xy, reacher.TARGET_SIZE + 0.01, color=colour, alpha=0.8))
ax1.set_aspect("equal")
ax1.set_xlim(-0.26, 0.26)
ax1.set_ylim(-0.26, 0.26)
ax1.set_title("reacher4: targets and a random policy")
ax1.legend(loc="lower left", fontsize=8)
ax2.plot(speeds, rewards_2, color="k")
ax2.set_xlabel("forward speed (m/s)")
ax2.set_ylabel("reward per step")
ax2.set_title("halfcheetah2: both directions pay")
plt.tight_layout()
plt.show()

# %% [markdown]
# ## What a random policy scores
#
# The floor of every later result. *Scaled return*, the paper's measure, puts the random
# policy at 0 and the expert at 1. Here each task runs uniformly random actions for a few
# episodes (`BUDGET.tour_episodes`); the demonstrations' manifest later records the random
# returns over 50 episodes that scaled returns are computed from.

# %%
stats = tour.random_returns(names, n_episodes=BUDGET.tour_episodes, seed=0)
random_table = pd.DataFrame(stats).T[["mean", "std", "n_episodes"]].round(1)
random_table

# %%
plots.return_bars(names, random_table["mean"], random_table["std"],
                  title=f"random policy, {BUDGET.tour_episodes} episodes per task")
plt.show()

# %% [markdown]
# A few things to notice. The cartpole starts almost balanced and its reward is smooth (pole
# up, cart centred), so even random pushes collect a good share of it until the pole falls.
# The reachers pay only inside a target, so a random arm scores whatever time it happens to
# spend there, more with more targets. The locomotion tasks pay for speed, which random
# actions almost never produce.
#
# ## A random episode, as a video

# %%
frames = render.episode_frames("halfcheetah2", rollout.RandomPolicy("halfcheetah2", seed=1),
                               seed=1, n_steps=BUDGET.video_steps, every=3,
                               height=120, width=160)
render.video(frames, fps=15)

# %% [markdown]
# ## From the paper's Gym tasks to our ports
#
# The paper ran OpenAI Gym's MuJoCo tasks; their code is not public. Where dm_control has the
# same robot we keep dm_control's model, and we keep its task (its reward in $[0, 1]$ per step
# and fixed 1000-step horizon) where a competent expert is reachable on a laptop CPU: cartpole,
# walker, the cheetahs and the humanoid. Two ports are Gym's robots written as dm_control
# domains, with Gym's objective rescaled to $[0, 1]$ per step: `ant`, because the suite has
# no ant, and `hopper`. The suite does have a hopper, but its hop task (start lying in a
# random orientation, no reward until hopping at speed) defeated every expert we could train
# here, and on the suite's model with Gym's objective PPO only learned to stand. So `hopper`
# is Gym's model (Gymnasium's `hopper.xml`), Gym's observation and Gym's reward divided by 4:
#
# $$r = \text{healthy} \cdot \operatorname{clip}\!\big((1 + v_x - 10^{-3}\lVert a\rVert^2) / 4,\ 0,\ 1\big),$$
#
# with $v_x$ the forward speed of the centre of mass and "healthy" Gym's test (torso above
# 0.7 m and within 0.2 rad of upright): standing still pays a quarter per step, hopping at
# 1 m/s a half, at 3 m/s or faster all of it. No port terminates early: a fallen walker or
# hopper simply stops earning reward (a hopper may get up again, but from lying down it
# practically cannot), which keeps every trajectory the same length for the density models
# of later chapters.

# %%
table[["paper task", "differs from the paper"]].style.set_properties(**{"text-align": "left"})

# %% [markdown]
# ## Under the hood: one step
#
# `env.step(action)` makes exactly the calls of dm_control's own `Environment.step`
# (`before_step`, `physics.step(n_sub_steps)`, `after_step`, reward, observation) but returns
# a flat vector instead of a `TimeStep` with an observation dictionary. `env.dm_env` is the
# genuine dm_control environment on the same physics; a unit test checks that the two give
# identical trajectories. Actions are clipped to $[-1, 1]$, which is what MuJoCo's actuator
# limits would do anyway, so the action a trajectory records is the one that was applied,
# and replaying it from the stored initial state reproduces the episode bit for bit.

# %%
traj = rollout.collect("walker", rollout.RandomPolicy("walker", seed=2), 1, seed=2,
                       max_steps=100)[0]
obs, rew = rollout.replay(traj)
print("replay identical:", np.array_equal(obs, traj.observations)
      and np.array_equal(rew, traj.rewards))

# %% [markdown]
# ## The experts and their demonstrations
#
# Imitation needs an expert. The paper trained its experts with TRPO on Gym's rewards; ours
# come from whatever method reaches a competent policy on a laptop CPU, and the
# demonstrations' manifest, `data/demos/manifest.json`, records for each task how its expert
# was made, the return of 50 expert episodes and 50 random ones (the two ends of the
# *scaled return*: expert 1, random 0; the expert's 50 are fresh episodes), how the 25
# stored demonstrations spread over the task's modes, and the command and revision that
# made them. `dc-lesson demos --task NAME` regenerates a task's file.
#
# * `cartpole`: a linear-quadratic regulator about the upright position, its cost read off
#   the task's reward. Not a learned policy, and nearly perfect.
# * `reacher1`, `reacher2`, `reacher4`: inverse kinematics to a target and a PD controller on
#   the joint angles. In the multi-target tasks **the expert goes to the target nearest the
#   fingertip at the first step**: its mode is a deterministic function of the observed start
#   state. That is deliberate. The paper's experts were Gaussian MLPs, the learner's own
#   class, so a learner *could* follow them exactly; a rule on the start state keeps that
#   true, and the demonstrations still split over every target, so a learner that collapses
#   onto one loses the others. The variant `reacher4-coin` (and `reacher2-coin`,
#   `halfcheetah2-coin`) picks the target by a hidden coin flip per episode instead: the
#   observation does not say which target was drawn, so no Markov single-Gaussian policy can
#   follow it, and chapter 04 uses it as the lesson on what such a policy cannot represent.
# * `halfcheetah`, `hopper`: policies trained with the library's PPO
#   (`dc-lesson expert train --task NAME`, one to three million steps, checkpointed so a run
#   survives interruption). `halfcheetah2` joins a forward and a backward runner, switched by
#   the start state (forward when the back thigh's first angle is at or above its median over
#   start states, so each runs about half the episodes; `halfcheetah2-coin` flips a coin). The hopper's PPO trains as Gym's does, with a
#   fallen hopper ending its training episode (`PPOConfig(terminate="hopper-fall")`, for
#   training only: the task itself never ends early).
# * `walker`, `ant` and `humanoid`: **soft actor-critic (SAC), distilled into the learners'
#   own network**. SAC (`dc_lesson.experts.sac`, CleanRL's loop: a tanh-squashed Gaussian actor,
#   twin Q networks with Polyak-averaged targets, a tuned entropy temperature) reuses every
#   transition many times, which is what a 2-core machine needs; our PPO stayed far below
#   these floors after 5M steps (the curves below). The SAC actor is then copied into a
#   `GaussianPolicy` of exactly BC's shape (64x64 tanh, an observation normaliser) by DAgger:
#   roll out the student, label the states it visits with the SAC actor's action, refit on
#   everything labelled so far (`dc_lesson.experts.network.distil`). So these experts are
#   Markov policies in the class every learner fits, as the paper's TRPO experts were.
# * The first expert of all three was a **planner on the true simulator**, kept as the
#   variant `planner` (`load_expert("humanoid", "planner")`,
#   `data/demos/humanoid-planner.npz`). Predictive sampling keeps a plan for the next half
#   second and at every control step tries 63 to 127 noisy variants of it on a copy of the
#   simulator, keeping the best; the humanoid plans with its walk reward plus a shaped "stay
#   tall and upright" term (`planner.PLANNING_REWARDS`: the walk reward is almost zero
#   whenever the head is low, so a falling planner sees no way back up) and is judged on the
#   task's own reward. It meets the floors, but it is no Markov policy (its action depends on
#   random plans, not only on the state), so BC cannot clone it (the walker's row below).
#   The humanoid's network needed a second SAC recipe: why the first run failed and what the
#   second does differently is under the SAC curves below.
#
# The table lists, for each task, the expert, its return over 50 episodes, the random
# policy's, and the mode shares (tasks without demonstrations yet say so).

# %%
from dc_lesson import data

manifest = data.read_manifest()["tasks"]
rows = []
for name in names:
    e = manifest.get(name)
    if e is None:
        rows.append({"task": name, "expert": "not yet generated"})
        continue
    rows.append({"task": name, "expert": e["expert"]["name"],
                 "expert return": f"{e['expert_return']['mean']:.1f} ± {e['expert_return']['std']:.1f}",
                 "random return": f"{e['random_return']['mean']:.1f} ± {e['random_return']['std']:.1f}",
                 "demos": str(e["n_trajectories"]),
                 "demo modes": ", ".join(f"{k} {v:.2f}" for k, v in e["demo_mode_shares"].items()),
                 "expert modes (50 ep.)": ", ".join(f"{k} {v:.2f}"
                                                   for k, v in e["expert_mode_shares"].items())})
pd.DataFrame(rows).set_index("task").fillna("")

# %% [markdown]
# The returns of the 25 demonstrations of each task, and, for the multi-target reacher,
# where the fingertip spends its time in them. The split over the targets is the split of the
# 25 start states, not an even one; the expert's own shares over 50 fresh episodes are in the
# table above. What a learner can hope to match is the demonstrations' split.

# %%
have = [n for n in names if n in manifest]
fig, axes = plt.subplots(1, 2, figsize=(11, 3.6), gridspec_kw={"width_ratios": [2, 1]})
demo_returns = [data.load_demos(n).returns for n in have]
axes[0].boxplot(demo_returns, tick_labels=have)
axes[0].set_ylabel("demonstration return")
axes[0].set_ylim(0, 1050)
axes[0].tick_params(axis="x", rotation=30)
if "reacher4" in manifest:
    tips4 = data.load_demos("reacher4").mode_features
    # Log colour scale: the expert rests on a target for most of an episode, and on a linear
    # scale its short paths between start and target would vanish.
    from matplotlib.colors import LogNorm
    axes[1].hist2d(tips4[:, 0], tips4[:, 1], bins=60, range=[[-0.26, 0.26], [-0.26, 0.26]],
                   cmap="Greys", cmin=1, norm=LogNorm())
    for xy, colour in zip(reacher.target_positions(4), reacher.target_colours(4)):
        axes[1].add_patch(plt.Circle(xy, reacher.TARGET_SIZE + 0.01, fill=False, color=colour,
                                     lw=2))
    axes[1].set_aspect("equal")
    axes[1].set_title("reacher4 demonstrations: fingertip")
plt.tight_layout()
plt.show()

# %% [markdown]
# ### Does each expert clear its bar?
#
# We set each task a floor, a return a clearly competent expert reaches (for example 700 for
# a reacher, whose targets must each be reached and held; 300 for a walking humanoid), and
# check it from the stored files with `dc_lesson.experts.floors`: the mean return over the
# 50 evaluation episodes, per mode for the multi-mode tasks, and for the hopper also whether
# it hops forward in every demonstration without falling (a mean return could hide one that
# stands still, which earns a quarter of the reward, or one that falls). An episode that
# arrives at no target is not a mode the expert must take; it is counted, and an expert
# whose demonstrations too often arrive nowhere misses its floor.
#
# A floor on return does not make an expert *imitable*. The last two columns are BC's scaled
# return from 25 of the expert's demonstrations, as the `clonable` study measured it (the
# mean over its seeds, 50 fresh episodes each: `dc-lesson sweep clonable`), and whether it
# reaches 0.5 (`floors.CLONE_FLOOR`; blank for the multi-mode tasks, which are Table I's).

# %%
from dc_lesson.experts import floors

floor_table = pd.DataFrame(floors.report()).set_index("task")
floor_table["BC from 25 demos"] = floor_table["BC from 25 demos"].map(
    lambda v: "" if pd.isna(v) else f"{v:.2f}")
floor_table["clonable"] = floor_table["clonable"].map(
    lambda v: "" if v is None or pd.isna(v) else ("yes" if v else "no"))
floor_table.round(1).fillna("")

# %% [markdown]
# The same measurement on the planner's demonstrations of the walker (the study's row
# `walker-planner`) says why the experts changed:

# %%
from IPython.display import Markdown, display
from dc_lesson.storage import read_result

clone_rows = read_result("clonable.json")["table"]
said = [f"BC from 25 demonstrations of the {r['expert']} expert of {r['task']}: "
        f"{r['scaled_return_mean']:.2f} ({r['seeds']} seed{'s' if r['seeds'] > 1 else ''})"
        for r in clone_rows if r["task"] == "walker"]
display(Markdown("; ".join(said) + "."))
missed = [r["task"] for r in clone_rows
          if r["demonstrations"] == r["task"] and not r["clonable"]]
if missed:
    display(Markdown("Not clonable by this bar: " + ", ".join(missed) + " (BC from all 25 "
                     "demonstrations stays below 0.5; the learners that start from BC there "
                     "start low)."))

# %% [markdown]
# Where the experts came from: the learning curves read from their training records
# (`data/experts/UNIT.json`). Top, our PPO runs: each point is the mean return of the
# training episodes that ended in one update, with the policy's sampling noise, so a little
# below what its mean action scores; the dashed line is the task's floor. The cheetahs clear
# it within a million steps, the hopper (its training episodes end when it falls, so the
# early ones are short) within a million, a quarter of an hour of this CPU; without that
# training-only termination, PPO's early falls left most of every 1000-step episode lying
# still. The walker's and the ant's PPO runs flatten out far below their floors after 5M
# steps (hours of this CPU). Bottom, SAC on those tasks and the humanoid: each point is the
# return of two evaluation episodes with the actor's mean action, against environment steps
# (the distilled networks' own returns are in the table above).

# %%
from dc_lesson.experts import network, trained

ppo_units = ["halfcheetah", "halfcheetah-backward", "hopper", "walker-ppo", "ant-ppo"]
sac_tasks = [t for t in network.SAC_RECIPES if network.paths(t)["sac_meta"].exists()]
fig, axes = plt.subplots(2, 5, figsize=(13, 5.4), sharey=True)
for ax, unit in zip(axes[0], ppo_units):
    curve = trained.learning_curve(unit)
    ax.plot(curve["steps"] / 1e6, curve["episode_return"], lw=1)
    ax.axhline(floors.FLOORS[curve["task"]], ls="--", c="grey", lw=1)
    if unit == "hopper":   # standing still earns a quarter of the reward at every step
        still = 0.25 * tasks.spec("hopper").horizon
        ax.axhline(still, ls=":", c="C3", lw=1)
        ax.text(0.05, still + 30, "standing still", fontsize=8, color="C3")
    ax.set_title(f"{unit} (PPO)\n{curve['training_seconds'] / 3600:.1f} h of training",
                 fontsize=9)
for ax, task in zip(axes[1], sac_tasks):
    curve = network.sac_curve(task)
    ax.plot(curve["steps"] / 1e6, curve["eval_return"], lw=1, c="C2")
    ax.axhline(floors.FLOORS[task], ls="--", c="grey", lw=1)
    ax.set_title(f"{task} (SAC)\n{curve['training_seconds'] / 3600:.1f} h of training",
                 fontsize=9)
for ax in axes[1][len(sac_tasks):]:
    ax.axis("off")
for ax in axes.flat:
    ax.set_xlabel("million steps")
for row in axes:
    row[0].set_ylabel("episode return")
axes[0, 0].set_ylim(0, 1000)
plt.tight_layout()
plt.show()
display(Markdown("; ".join(
    f"{t}: SAC's best evaluation return {c['eval_return'].max():.0f} (floor "
    f"{floors.FLOORS[t]:.0f}) in {c['steps'][-1]:,} steps"
    + ("" if c["done"] else f" of the recipe's {c['total_steps']:,} (the run is under way: "
       f"dc-lesson expert train --task {t} resumes it)")
    for t, c in ((t, network.sac_curve(t)) for t in sac_tasks)) + "."))

# %% [markdown]
# **Why the humanoid's first SAC run stayed on the floor.** That run ended each training
# episode when the head dropped below `tasks.humanoid.FALLEN_HEAD` (Gym's fallen humanoid).
# The planner's demonstrations show what that meant: dm_control drops the humanoid from a
# random pose, and even the planner falls first and then gets up. So the run ended almost
# every episode before there was anything to learn. The second recipe, the one in the curve
# above, has no termination and begins half of its training episodes at a state of the
# planner's demonstrations (reference state initialisation, Peng et al. 2018:
# `SACConfig.demo_starts`), so it meets standing and walking states and tries its own actions
# there. Putting the planner's transitions in every minibatch instead (RLPD, `demo_fraction`)
# made the critic's values diverge at the demonstrated actions, which the agent never tries
# (the measurements are written with the recipe, `experts.network.SAC_RECIPES`).

# %%
from dc_lesson.storage import read_json
from dc_lesson.tasks import humanoid as humanoid_task

planner_demos = network.sac_demonstrations("humanoid")
falls = [humanoid_task.fell(t.observations) for t in planner_demos]
first_fall = np.array([int(np.argmax(f)) for f in falls if f.any()])
first_run = read_json(network.FIRST_HUMANOID_RUN, "the first humanoid SAC record")
second = network.sac_curve("humanoid")
above = second["steps"][second["eval_return"] >= floors.FLOORS["humanoid"]]
first_curve = np.array([r["episode_return"] for r in first_run["learning_curve"]])
display(Markdown(
    f"In {int((first_fall < 30).sum())} of the planner's {len(planner_demos)} demonstrations "
    f"the head is below {humanoid_task.FALLEN_HEAD} m within 30 steps (median first step "
    f"{np.median(first_fall):.0f}); their mean return is "
    f"{np.mean([t.ret for t in planner_demos]):.0f}. The first run's evaluation returns over "
    f"{first_run['steps']:,} steps: at most {first_curve.max():.0f}, the last "
    f"{first_curve[-1]:.0f}. The second recipe's run "
    + (f"first evaluated above the floor at {above[0]:,} steps, after a long stretch at "
       f"the random level (an earlier run of the same recipe on another machine, other "
       f"rounding and so another trajectory, took off hundreds of thousands of steps "
       f"sooner: the recipe's comment gives both)." if len(above) else
       f"has not yet been evaluated above the floor ({second['steps'][-1]:,} steps).")))

# %% [markdown]
# **The humanoid: DAgger from the planner.** The first SAC run did not reach the humanoid's
# floor, so we also tried the other route issue 39 names: ask the planner itself. DAgger
# (Ross, Gordon and Bagnell 2011) rolls out a mixture of the planner and a student network,
# has the planner label every state the episodes reach with the action it would take there
# (it plans from the exact simulator state), and refits the student (BC's 64x64 network) on
# every label so far (`dc-lesson expert dagger --task humanoid`,
# `experts/planner_dagger.py`). In round 0
# the planner acts alone; in round r it acts at each step with probability 0.5^r and the
# student otherwise, so the rounds drift from the planner's states into the student's. Each
# round is 2 episodes of 400 steps; a label costs one whole plan (about a quarter of a
# second on one core). Below: each round's return over its 400 steps; the student's
# own return over whole episodes once the run has ended.

# %%
from dc_lesson.experts import planner_dagger

dagger = planner_dagger.record("humanoid")
if dagger is None:
    print("no DAgger run on record for the humanoid: dc-lesson expert dagger --task humanoid")
else:
    rounds = dagger["rounds"]
    fig, ax = plt.subplots(figsize=(6, 2.8))
    ax.plot([r["round"] for r in rounds], [r["return"] for r in rounds], "o-", lw=1)
    ax.set_xlabel("DAgger round (the planner acts with probability 0.5^round)")
    ax.set_ylabel(f"return over {rounds[0]['steps']} steps")
    ax.set_title("humanoid: DAgger from the planner")
    plt.tight_layout()
    plt.show()
    planner_level, last = rounds[0]["return"], rounds[-1]
    said = (f"The planner alone returned {planner_level:.0f} over {rounds[0]['steps']} steps; "
            f"after {len(rounds)} rounds ({last['labels']:,} labels, the student's squared "
            f"error on them {last['mse']:.3f}) the mixed episodes returned "
            f"{last['return']:.1f}, the planner acting at {last['beta']:.2%} of the steps. "
            f"The labels vary by {dagger['label_variance']:.3f} per action dimension, so the "
            f"student explains {1 - last['mse'] / dagger['label_variance']:.0%} of their "
            f"variance. Part of the rest is no function of the state at all (the planner's "
            f"sampling noise, the memory of its plan), which is also why BC cannot clone the "
            f"planner; and a student that errs this much at every step falls within a few "
            f"dozen steps, so the later rounds label a body on the floor.")
    if dagger["done"]:
        r = dagger["student_return"]
        meets = r["mean"] >= floors.FLOORS["humanoid"]
        said += (f" The student alone returns {r['mean']:.1f} (std {r['std']:.1f}, "
                 f"{r['n_episodes']} whole episodes) against the floor of "
                 f"{floors.FLOORS['humanoid']:.0f}: " + (
                     "it meets the floor." if meets else
                     "far below it; the humanoid's expert is the second SAC recipe's "
                     "network instead (above)."))
    else:
        said += (f" The run has not finished ({len(rounds)} of "
                 f"{dagger['config']['rounds']} rounds on record).")
    display(Markdown(said))

# %% [markdown]
# Every expert, seen through its first demonstration: frames replayed from the stored
# initial state and actions (so no expert has to run here), at the start, a quarter, half
# and the end of the episode.

# %%
steps = [0, 250, 500, 1000]
fig, axes = plt.subplots(len(have), len(steps), figsize=(1.9 * len(steps), 1.5 * len(have)))
for row, name in zip(np.atleast_2d(axes), have):
    demo = data.load_demos(name, n_trajectories=1).trajectories[0]
    for ax, step, img in zip(row, steps, render.trajectory_frames(demo, steps, 96, 128)):
        ax.imshow(img)
        ax.set_xticks([])
        ax.set_yticks([])
        if name == have[0]:
            ax.set_title(f"step {step}", fontsize=9)
    row[0].set_ylabel(name, fontsize=9)
plt.tight_layout()
plt.show()

# %% [markdown]
# An expert at work: the `reacher4` expert, three episodes whose start states differ.

# %%
from dc_lesson.experts import load_expert

expert4, _ = load_expert("reacher4")
clips = []
for seed in (0, 1, 2):
    clips += render.episode_frames("reacher4", expert4, seed=seed,
                                   n_steps=min(60, BUDGET.video_steps), every=3,
                                   height=120, width=120)
render.video(clips, fps=15)

# %% [markdown]
# ## How fast is a step?
#
# Everything later in the book is bounded by how fast we can collect experience, so the
# library steps many copies of a task in lockstep (`tasks.load_vec`): one call into MuJoCo's
# batch API (`mujoco.batch`, one thread) sets every copy's controls and advances its physics,
# then one NumPy pass computes every copy's observation, reward and mode feature, to the bit
# what stepping each copy through dm_control gives (a test compares them over whole
# episodes). The benchmark `dc-lesson perf rollout` times this
# path against raw `mujoco.mj_step` on the same model (the ceiling: physics and nothing else)
# and against dm_control's own `Environment.step`, and, where the optional extra EnvPool (C++
# batched environments of the same models) was installed when it ran, against EnvPool with as
# many environments and one thread. Its stored result,
# `data/results/bench_rollout.json`, records the command, machine and revision; a test checks
# the two claims below against it.
#
# * The rollout path is faster than dm_control's `Environment.step` on every task.
# * For the tasks that take several physics steps per control step (hopper, walker, ant,
#   humanoid), it reaches at least half the throughput of raw physics stepping. For the tasks
#   with a single physics step per control step the physics is so cheap (a few microseconds)
#   that Python's bookkeeping dominates and the ratio is lower.

# %%
from dc_lesson.storage import read_result

bench = read_result("bench_rollout.json")
speed = pd.DataFrame(bench["rows"]).set_index("task")
print(f"command: {bench['command']}   revision: {bench['revision'][:12]}   "
      f"budget: {bench['budget']}")
columns = ["physics steps per control step", "raw mj_step (ctrl steps/s)", "dm_control Environment",
           "dc_lesson rollout", "rollout / raw", "rollout / dm_control"]
if "rollout / EnvPool" in speed:   # EnvPool (C++ batched environments) where it was installed
    columns += ["EnvPool", "rollout / EnvPool"]
speed[columns].round(2)

# %% [markdown]
# How many copies should a batch hold? Each control step pays a fixed price (one call into
# MuJoCo, one NumPy pass, one policy call) whatever the number of copies, so the ratio to raw
# physics grows with the batch until the physics dominates. The same benchmark steps one
# single-substep task with 1 to 64 copies. The library's evaluations and demonstrations step
# 16 copies at a time (`rollout.collect`'s default); PPO, and the learners built on it,
# collect with 8 (`PPOConfig.n_envs`), a choice about learning as much as speed: with a fixed
# batch of interactions, more copies mean shorter stretches of each episode per update.
# (How long a learner's whole run takes, and how the library's speed work shortened it, is
# maintainers' material, in `dc_lesson/perf/HISTORY.md`.)

# %%
sweep = pd.DataFrame(bench["batch_sweep"]).set_index("batch")
print(f"{sweep['task'].iloc[0]}: rollout / raw by environments per batch")
sweep[["dc_lesson rollout", "rollout / raw"]].round(2).T

# %% [markdown]
# ## Summary
#
# * Ten dm_control tasks stand in for the paper's ten Gym tasks; `tasks.make(name, seed)`
#   builds any of them, with flat observations, rewards in $[0, 1]$ and 1000-step episodes.
# * Three of them (`reacher2`, `reacher4`, `halfcheetah2`) have several equally rewarded
#   behaviours that the policy, not the observation, decides between.
# * Each task has a mode feature, the low-dimensional summary of where a policy goes that the
#   book's coverage plots and distances are computed on.
#
# ## Exercises
#
# 1. Put the `reacher4` fingertip on the green target by setting the two joint angles (the
#    upper arm and forearm are both 0.12 m long) and check that the reward is 1. A solution
#    is filled in; change it and rerun the check.
# 2. What is the `halfcheetah` (one direction) reward at a forward speed of $-5$ m/s, and why
#    does that make `halfcheetah2` a different task? Check your answer with the environment.
# 3. Why does a fixed horizon with no early termination matter for an imitation learner that
#    models the *distribution* of states it visits? (Think of what a fallen walker's states
#    look like, and how many of them an episode then contains.)

# %%
# Exercise 1: a solution by two-link inverse kinematics (elbow-up branch).
env = tasks.make("reacher4", seed=0)
env.reset()
green = reacher.target_positions(4)[reacher.target_colours(4).index("green")]
l1 = l2 = 0.12
x, y = green
q2 = np.arccos((x * x + y * y - l1 * l1 - l2 * l2) / (2 * l1 * l2))
q1 = np.arctan2(y, x) - np.arctan2(l2 * np.sin(q2), l1 + l2 * np.cos(q2))
env.physics.data.qpos[:] = [q1, q2]
env.physics.forward()
assert env.task.get_reward(env.physics) == 1.0, "the fingertip is not in the green target"
print("fingertip at", env.mode_feature().round(3), "- reward", env.task.get_reward(env.physics))

# %%
# Exercise 2: the one-direction task pays nothing for running backwards.
env1 = tasks.make("halfcheetah", seed=0)
env1.reset()
env1.physics.data.qvel[0] = -5.0
env1.physics.forward()
assert env1.task.get_reward(env1.physics) == 0.0
print("halfcheetah reward at -5 m/s:", env1.task.get_reward(env1.physics))
