"""Networks: the Gaussian policy and value network every learner shares, and model files.

``policies`` holds :class:`~dc_lesson.nn.policies.GaussianPolicy`,
:class:`~dc_lesson.nn.policies.ValueNetwork` and saving / loading them; ``checkpoint`` the one
atomic, checked way every model file (policy, checkpoint, flow) is written and read.
"""

from dc_lesson.nn import checkpoint, policies
from dc_lesson.nn import mixture
from dc_lesson.nn.mixture import MixturePolicy
from dc_lesson.nn.policies import GaussianPolicy, StochasticPolicy, ValueNetwork, load_policy, save_policy

__all__ = ["GaussianPolicy", "StochasticPolicy", "ValueNetwork", "checkpoint", "load_policy",
           "policies", "save_policy"]
