"""``python -m cdpr_sym``: the command line."""

import sys

from cdpr_sym.cli import main

sys.exit(main())
