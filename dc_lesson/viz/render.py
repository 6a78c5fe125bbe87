"""Frames and short videos of the task ports, headless (``MUJOCO_GL=egl``), for notebooks.

Videos are animated GIFs embedded in HTML: they play in JupyterLab and on GitHub without
ffmpeg, and a few dozen small frames keep a notebook light.
"""

from __future__ import annotations

import base64
import io

import numpy as np

from dc_lesson import tasks as _tasks
from dc_lesson.data.rollout import Policy, as_batch_policy, check_policy


def frame(task: str, seed: int = 0, height: int = 240, width: int = 320,
          camera=None) -> np.ndarray:
    """A frame of ``task`` at the start of the episode drawn with ``seed``: (H, W, 3) uint8."""
    env = _tasks.make(task)
    env.reset(seed=seed)
    return env.render(height=height, width=width, camera_id=camera)


def episode_frames(task: str, policy: Policy, seed: int = 0, n_steps: int = 100,
                   every: int = 2, height: int = 180, width: int = 240,
                   camera=None) -> list[np.ndarray]:
    """Runs one episode of ``policy`` for ``n_steps`` and renders every ``every``-th step.

    A policy that plans on the simulator (``attach``, see :func:`dc_lesson.data.rollout.collect`)
    is attached to this episode's environment first."""
    check_policy(task, policy)   # a policy of another task: a clear error, not a shape error
    env = _tasks.make(task)
    # one copy stepped on its own Physics (not batched), so the Physics it renders is current
    venv = _tasks.VecEnv([env], batched=False)
    act = as_batch_policy(policy)
    if hasattr(policy, "attach"):
        policy.attach(venv)
    obs, _ = venv.reset([seed])
    if hasattr(policy, "reset"):
        policy.reset(np.array([seed], dtype=np.int64))
    frames = [env.render(height, width, camera)]
    for t in range(min(n_steps, env.spec.horizon)):
        a = np.asarray(act(obs), dtype=np.float64).reshape(1, -1)
        obs, _, _, _ = venv.step(a)
        if (t + 1) % every == 0:
            frames.append(env.render(height, width, camera))
    return frames


def trajectory_frames(traj, steps, height: int = 120, width: int = 160,
                      camera=None) -> list[np.ndarray]:
    """Frames of a stored trajectory at control steps ``steps`` (0 = its initial state),
    replayed from its initial state with its stored actions: no expert needs to run."""
    env = _tasks.make(traj.task)
    env.reset(seed=traj.seed)
    env.set_state(traj.initial_state)
    wanted = sorted(set(int(s) for s in steps))
    if wanted and not 0 <= wanted[0] <= wanted[-1] <= len(traj.actions):
        raise ValueError(f"steps must lie in [0, {len(traj.actions)}], got {wanted}")
    frames = {}
    for t in range(wanted[-1] + 1 if wanted else 0):
        if t in wanted:
            frames[t] = env.render(height, width, camera)
        if t < len(traj.actions) and t < wanted[-1]:
            env.step(traj.actions[t])
    return [frames[int(s)] for s in steps]


def gif_bytes(frames: list[np.ndarray], fps: float = 20) -> bytes:
    from PIL import Image
    if not frames:
        raise ValueError("no frames to encode")
    images = [Image.fromarray(np.asarray(f, dtype=np.uint8)) for f in frames]
    buf = io.BytesIO()
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:],
                   duration=int(1000 / fps), loop=0)
    return buf.getvalue()


def video(frames: list[np.ndarray], fps: float = 20):
    """An ``IPython.display.HTML`` that plays ``frames`` as a looping animation."""
    from IPython.display import HTML
    data = base64.b64encode(gif_bytes(frames, fps)).decode()
    return HTML(f'<img src="data:image/gif;base64,{data}"/>')
