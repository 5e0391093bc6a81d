"""python -m adrc_offboard"""

import sys

from adrc_offboard.cli import main

sys.exit(main())
