"""``python -m imitate``: the ``imitate`` command (see :mod:`imitate.cli`)."""

import sys

from imitate.cli import main

sys.exit(main())
