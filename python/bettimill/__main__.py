"""``python -m bettimill ARGS``: the same CLI as the ``bettimill`` console script."""

import sys

from ._cli import main

sys.exit(main())
