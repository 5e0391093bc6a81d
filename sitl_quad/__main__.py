"""python -m sitl_quad"""

import sys

from sitl_quad.cli import main

sys.exit(main())
