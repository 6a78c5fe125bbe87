"""Density models of expert states: SoftFlow, a noise-conditioned continuous normalizing flow.

``softflow`` is the readable module (the flow, its training, its files); its fast exact-trace
kernels live beside it in the private ``_trace`` module.
"""

from dc_lesson.density import softflow

__all__ = ["softflow"]
