"""``reacher1``, ``reacher2``, ``reacher4``: a two-link planar arm and K fixed targets.

The paper's Reacher-v2 draws one random target per episode and shows it to the policy; its
multi-target variants (Reacher2, Reacher4) have fixed targets that the policy does *not* see, so
which target an episode goes to is a property of the policy: the behaviour modes.  The port uses
dm_control's reacher arm (0.12 m upper arm, 0.12 m forearm to the fingertip) with the targets
placed on a circle of radius ``TARGET_RADIUS`` at fixed angles:

=========  ===========================  =========================
task       target angles (degrees)      colours (as the paper's)
=========  ===========================  =========================
reacher1   45                           red
reacher2   45, 225                      red, blue
reacher4   45, 135, 225, 315            red, green, blue, yellow
=========  ===========================  =========================

Reward per step is 1 while the fingertip is inside *any* target (within target + finger radius,
as the suite's reacher) and 0 otherwise, so every target is equally good.  The observation is
(cos, sin) of both joint angles, the fingertip's x-y position and the two joint velocities
(8 numbers); there is no target in it.  Episodes start from uniformly random joint angles
(the suite's randomiser) at rest.
"""

from __future__ import annotations

import collections

import numpy as np
from dm_control.suite import reacher as suite_reacher
from dm_control.suite.utils import randomizers

from dc_lesson.tasks.base import NO_MODE, PortTask, TaskSpec, name_id

TARGET_RADIUS = 0.16   # distance of each target from the shoulder (m); the reach is 0.24
TARGET_SIZE = 0.03     # radius of a target sphere (m)
FINGER_SIZE = 0.01     # radius of the fingertip sphere (dm_control's reacher.xml; a test checks)
ARRIVE_RADIUS = TARGET_SIZE + FINGER_SIZE   # inside a target: where the reward pays 1
STAY_FRACTION = 0.9    # an episode's mode: the target it is inside for 90% of its last quarter
_COLOURS = {45: ("red", "0.85 0.15 0.15 1"), 135: ("green", "0.15 0.7 0.2 1"),
            225: ("blue", "0.15 0.35 0.9 1"), 315: ("yellow", "0.95 0.8 0.1 1")}
ANGLES = {1: (45,), 2: (45, 225), 4: (45, 135, 225, 315)}


def target_positions(n_targets: int) -> np.ndarray:
    """(K, 2) x-y positions of the targets of ``reacher{K}``."""
    ang = np.deg2rad(np.array(ANGLES[n_targets], dtype=np.float64))
    return TARGET_RADIUS * np.stack([np.cos(ang), np.sin(ang)], axis=1)


def target_colours(n_targets: int) -> tuple[str, ...]:
    return tuple(_COLOURS[a][0] for a in ANGLES[n_targets])


def _spec(k: int) -> TaskSpec:
    paper = "Reacher-v2" if k == 1 else f"Reacher{k} ({k} fixed targets)"
    differs = ("one fixed target that is not observed (Gym draws a random target per episode "
               "and observes it); reward 1 inside the target, else 0" if k == 1 else
               f"{k} fixed unobserved targets, reward 1 inside any of them, else 0")
    return TaskSpec(
        name=f"reacher{k}", paper_task=paper, base="suite reacher arm, custom targets",
        obs_dim=8, act_dim=2, horizon=1000, control_timestep=0.02, n_sub_steps=1,
        mode_feature_names=("fingertip x", "fingertip y"),
        modes=target_colours(k) if k > 1 else (), differs=differs)


SPECS = {k: _spec(k) for k in ANGLES}


def get_model_and_assets(n_targets: int):
    xml, assets = suite_reacher.get_model_and_assets()
    xml = xml.decode() if isinstance(xml, bytes) else xml
    old = '<geom name="target" pos="0 0 .01" material="target" type="sphere" size=".05"/>'
    if old not in xml:  # pragma: no cover - guards against a changed dm_control
        raise RuntimeError("dm_control's reacher.xml changed: cannot place the targets")
    geoms = []
    for i, (x, y) in enumerate(target_positions(n_targets)):
        _, rgba = _COLOURS[ANGLES[n_targets][i]]
        geoms.append(f'<geom name="target{i}" pos="{x:.6f} {y:.6f} .01" type="sphere" '
                     f'size="{TARGET_SIZE}" rgba="{rgba}" contype="0" conaffinity="0"/>')
    return xml.replace(old, "\n    ".join(geoms)), assets


class Physics(suite_reacher.Physics):
    def fingertip(self) -> np.ndarray:
        """x-y position of the fingertip."""
        return self.named.data.geom_xpos["finger", :2].copy()


class ReachAny(PortTask):
    """Reach any of the fixed targets and stay there."""

    camera = "fixed"
    fields = ("qpos", "qvel", "geom_xpos")

    def __init__(self, n_targets: int, random=None):
        self.n_targets = n_targets
        self.targets = target_positions(n_targets)
        super().__init__(random=random)

    def resolve(self, model):
        finger = name_id(model, "geom", "finger")
        targets = [name_id(model, "geom", f"target{k}") for k in range(self.n_targets)]
        if targets != list(range(targets[0], targets[0] + len(targets))):  # pragma: no cover
            raise RuntimeError("the reacher's target geoms are not consecutive in the model")
        # the targets as a slice of the geoms: a view of them, where a list index copies
        return {"finger": finger, "targets": targets,
                "target_slice": slice(targets[0], targets[0] + len(targets)),
                "radii": TARGET_SIZE + float(model.geom_size[finger, 0])}

    def initialize_episode(self, physics):
        randomizers.randomize_limited_and_rotational_joints(physics, self.random)
        super().initialize_episode(physics)

    def _fingertip(self, b):
        return b.geom_xpos[:, b.ids["finger"], :2]

    def batch_observation(self, b):
        # (cos, sin) of each joint angle, interleaved: two ufunc calls instead of four and a
        # stack (the same values, tests/test_tasks.py)
        q = b.qpos[:, :2]
        position = np.empty((len(q), 4))
        position[:, 0::2] = np.cos(q)
        position[:, 1::2] = np.sin(q)
        return collections.OrderedDict(position=position, fingertip=self._fingertip(b),
                                       velocity=b.qvel)

    def batch_reward(self, b):
        # 1 inside any target (centre distance within target + finger radius), as the suite's
        # ``rewards.tolerance(dist, (0, radii))`` with no margin, which is the indicator of
        # ``0 <= dist <= radii``; a distance is never negative, so the indicator of
        # ``dist <= radii`` (False for NaN, as the tolerance's).  The distance as
        # ``np.linalg.norm(axis=2)`` computes it (a sum of two squares is their one addition).
        # The same floats; a test holds them together.
        to_targets = b.geom_xpos[:, b.ids["target_slice"], :2] - self._fingertip(b)[:, None]
        sq = to_targets * to_targets
        dist = np.sqrt(sq[..., 0] + sq[..., 1])
        return (dist <= b.ids["radii"]).any(axis=1).astype(np.float64)

    def batch_mode_feature(self, b):
        return self._fingertip(b)

    def classify_mode(self, features):
        # Index of the nearest target to each fingertip position.
        f = np.asarray(features)[..., None, :2]
        return np.argmin(np.linalg.norm(f - self.targets, axis=-1), axis=-1)

    def episode_mode(self, mode_features):
        """The target the fingertip arrived at and stayed at: inside it (the reward's radius,
        target + finger) in at least ``STAY_FRACTION`` of the last quarter's steps; else
        ``NO_MODE``.  Hovering between targets, or reaching one and leaving, is no mode."""
        if self.n_targets == 1:
            return 0   # a single-mode task: every episode takes its one mode
        f = np.asarray(mode_features)[-max(1, len(mode_features) // 4):, None, :2]
        inside = np.linalg.norm(f - self.targets, axis=-1) <= ARRIVE_RADIUS   # (steps, K)
        share = inside.mean(axis=0)
        k = int(share.argmax())
        return k if share[k] >= STAY_FRACTION else NO_MODE
