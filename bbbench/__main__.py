"""`python -m bbbench`: the same as the `bbbench` command."""

import sys

from bbbench.cli import main

sys.exit(main())
