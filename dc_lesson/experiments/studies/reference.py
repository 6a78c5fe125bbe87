"""Fresh expert episodes, one cell per task (:func:`protocol.reference_cell`): the reference
every study scores its learners against.  It lists no cells of its own; the studies' cells
need it, and a sweep runs it first."""

from dc_lesson.experiments import protocol
from dc_lesson.experiments.cells import Study

STUDY = Study("reference", "fresh expert episodes per task (the evaluation's reference)",
              cells=lambda budget: [], run_cell=protocol.run_reference)
