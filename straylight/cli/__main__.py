"""``python -m straylight.cli``: the ``straylight`` command."""

import sys

from straylight.cli import main

sys.exit(main())
