"""What a reader sees: ``render`` (frames and videos of episodes) and ``plots`` (figures)."""

from dc_lesson.viz import plots, render

__all__ = ["plots", "render"]
