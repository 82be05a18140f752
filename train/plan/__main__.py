"""``python -m train.plan``: the same as ``ikbranch plan``."""

import sys

from .cli import main

sys.exit(main())
