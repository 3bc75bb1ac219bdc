"""``python -m tlfleet.cli …``: the ``tlfleet`` command, as the coordinator starts its children."""

import sys

from tlfleet.cli.main import main

sys.exit(main())
