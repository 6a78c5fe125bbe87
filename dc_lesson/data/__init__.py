"""Data: typed trajectories, the demonstrations on disk, and collecting new episodes.

* ``types``: :class:`Trajectory` (one validated, immutable episode) and :class:`Demonstrations`;
  ``subsample`` (GAIL's protocol: every 20th pair of each demonstration, from a random offset);
* ``store``: ``load_demos(task, n_trajectories, seed)``, the manifest, sha256 checks;
* ``rollout``: collecting episodes from any policy, batched, and exact replay;
* ``modes``: which behaviour mode an episode took, and mode shares.

The most used names are re-exported here: ``from dc_lesson import data; data.load_demos(...)``.
"""

from dc_lesson.data import types
from dc_lesson.data.types import Demonstrations, Trajectory, TrajectoryError, subsample
from dc_lesson.data import store
from dc_lesson.data.store import (DEMO_FORMAT, DEMOS_DIR, DemoError, demo_path, demo_set, load_demos,
                                  manifest_entry,
                                  read_demo_file, read_manifest, regenerate_hint, save_demos,
                                  sha256)
from dc_lesson.data import convert, modes, rollout

__all__ = ["DEMOS_DIR", "DEMO_FORMAT", "DemoError", "Demonstrations", "Trajectory",
           "TrajectoryError", "convert", "demo_path", "demo_set", "load_demos", "manifest_entry", "modes", "read_demo_file",
           "read_manifest", "regenerate_hint", "rollout", "save_demos", "sha256", "store", "subsample",
           "types"]
