"""``python -m dc_lesson.cli``: the ``dc-lesson`` command."""

import sys

from dc_lesson.cli import main

sys.exit(main())
