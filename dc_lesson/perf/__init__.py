"""Throughput benchmarks only (no science): ``rollout`` (our engine against dm_control's loop
and raw MuJoCo) and ``softflow`` (SoftFlow's fast trace against a naive CNF).  Each prints
ratios measured within one run; ``dc-lesson perf NAME`` runs one.  ``HISTORY.md`` beside them
tells how the library got faster (whole runs before and after issue 14, DC's flow numerics)."""
