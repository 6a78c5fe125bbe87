"""The studies behind every stored result, one module per learner's studies, and the verdicts.

* ``bc``: scaled return against the number of demonstrations; compounding error (drift);
* ``gail``: BC and GAIL on the multi-mode tasks; GAIL against its learning rate;
* ``dc``: BC, GAIL and DC on the multi-mode tasks; DC's loop, learning-rate and ADMM ablations;
* ``softflow``: SoftFlow fitted to the circle toy and to expert states;
* ``protocol``: what the studies share (evaluation seeds, stored mode features, the fresh
  expert reference and the expert row);
* ``cells``, ``sweep``, ``aggregate``, ``studies``: every result a cell; the Ray sweep that runs a
  study's missing cells (``dc-lesson sweep NAME``); cells -> ``data/results/NAME.json``;
* ``claims``: the paper's claims, each judged by a declared paired interval;
* ``report``: what a chapter calls to render a number, an interval or a verdict;
* ``headline``: the main job's comparison; ``tour``: the tour of the ten tasks.

``dc-lesson bench NAME`` runs a study and writes its file under ``data/results/``.
"""
