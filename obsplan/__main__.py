"""``python -m obsplan`` runs the ``obsplan`` command."""

import sys

from obsplan.cli import main

sys.exit(main())
