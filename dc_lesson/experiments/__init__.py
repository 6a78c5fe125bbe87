"""The studies behind every stored result, one module per learner's studies, and the verdicts.

* ``bc``: scaled return against the number of demonstrations; compounding error (drift);
* ``gail``: BC and GAIL on the multi-mode tasks; GAIL against its learning rate;
* ``dc``: BC, GAIL and DC on the multi-mode tasks; DC's loop, learning-rate and ADMM ablations;
* ``softflow``: SoftFlow fitted to the circle toy and to expert states;
* ``protocol``: what the studies share (evaluation seeds, stored mode features);
* ``claims``: the paper's claims judged from the result files;
* ``headline``: the main job's comparison; ``tour``: the tour of the ten tasks.

``dc-lesson bench NAME`` runs a study and writes its file under ``data/results/``.
"""
