"""`python -m planner`: the route planner's command line (planner.cli)."""

import sys

from planner.cli import main

sys.exit(main())
