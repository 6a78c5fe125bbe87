"""The studies behind every stored result, the runs they are made of, and the verdicts.

* ``bc``: one BC run against the number of demonstrations; compounding error (drift);
* ``gail``: one GAIL run from the BC warm start, both evaluated;
* ``dc``: one DC run from the BC warm start, both evaluated (the hopper ablations' run);
* ``softflow``: SoftFlow fitted to the circle toy and to expert states;
* ``protocol``: what the studies share (evaluation seeds, stored mode features, the fresh
  expert reference and the expert row);
* ``cells``, ``sweep``, ``aggregate``, ``studies``: every result a cell; the Ray sweep that runs a
  study's missing cells (``dc-lesson sweep NAME``); cells -> ``data/results/NAME.json``;
* ``claims``: the paper's claims, each judged by a declared paired interval;
* ``report``: what a chapter calls to render a number, an interval or a verdict;
* ``headline``: the main job's comparison; ``tour``: the tour of the ten tasks.

``dc-lesson sweep NAME`` runs a study's cells and ``dc-lesson aggregate NAME`` writes its file
under ``data/results/``.
"""
