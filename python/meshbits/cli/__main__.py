"""``python -m meshbits.cli``: the ``meshbits`` program."""

import sys

from .main import main

sys.exit(main())
