"""dc-lesson: the library behind the textbook on Distributional Cloning (DC).

The package is layered; a module imports only from its own layer or the ones above it in this
list (``tests/test_layers.py`` checks it):

* ``budget``, ``storage``, ``progress``, ``checks``, ``timing``: the smoke / lesson / paper
  presets; where the data folder is and how files are written (atomic, with provenance);
  progress bars; the field checks every configuration makes at construction; named phases a
  run can time;
* ``tasks``: the ten dm_control task ports; ``tasks.load`` gives a dm_env environment,
  ``gymnasium.make("dc_lesson/NAME-v0")`` a Gymnasium one, ``tasks.make`` the fast engine;
* ``data``: typed, validated trajectories, the demonstrations on disk (sha256-checked),
  collecting episodes (``data.rollout``), mode shares, converters to other libraries;
* ``nn``: the Gaussian policy and value network, and the one checked way to save models
  (``nn.checkpoint``: atomic, with a sha256 sidecar checked before loading);
* ``density``: ``density.softflow``, SoftFlow, a noise-conditioned continuous normalizing flow;
* ``algorithms``: the learners, one module each (``algorithms.bc``, ``algorithms.ppo``,
  ``algorithms.gail``, ``algorithms.dc``), one ``train`` interface (``algorithms.base``) and
  the registry ``algorithms.ALGORITHMS``;
* ``experts``: the scripted, PPO-trained and SAC-distilled experts (the sampling planner as a
  variant), their floors, making the demonstrations;
* ``evaluation``: ``evaluation.metrics`` (EMD, KL and reverse KL, scaled return) and
  ``evaluation.evaluate`` (``evaluate_policy``, one way to evaluate every learner);
* ``viz``: frames, videos and figures;
* ``experiments``: the studies behind every stored result, and the paper's claims judged;
  ``perf``: throughput benchmarks;
* ``cli``: the ``dc-lesson`` command; ``notebook``: what every chapter does first.
"""

import os
import sys

# MuJoCo picks its OpenGL backend when dm_control is first imported.  With no screen (a server,
# CI, a notebook on a remote kernel) the only backend that works out of the box is EGL, so make
# it the default there; a user's own MUJOCO_GL always wins.
if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
    os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"
