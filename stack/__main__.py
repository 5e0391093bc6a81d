"""`python -m stack`: `buoy-gcs` (`up`, and the ground station's `serve` and `report`)."""

import sys

from stack.cli import main

sys.exit(main())
