"""dc-lesson: the library behind the textbook on Distributional Cloning (DC).

Modules: ``tasks`` (the ten dm_control ports), ``data`` (typed trajectories and the
demonstrations on disk), ``rollout`` (collecting episodes), ``policies`` (Gaussian MLP policy,
value network), ``ppo`` (PPO with a pluggable reward), ``experts`` (scripted and trained
experts), ``demos`` (making demonstrations), ``render`` and ``plots`` (frames, videos,
figures), ``budget`` (smoke / lesson / paper presets), ``bench`` (throughput benchmarks),
``results`` (result files with provenance), ``cli`` (the ``dc-lesson`` command).
"""

import os
import sys

# MuJoCo picks its OpenGL backend when dm_control is first imported.  With no screen (a server,
# CI, a notebook on a remote kernel) the only backend that works out of the box is EGL, so make
# it the default there; a user's own MUJOCO_GL always wins.
if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
    os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"
