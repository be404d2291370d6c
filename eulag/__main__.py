"""``python -m eulag``: the eulag command line."""

import sys

from eulag.cli import main

sys.exit(main())
