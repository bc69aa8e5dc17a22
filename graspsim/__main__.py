"""``python -m graspsim`` runs the command line."""

import sys

from graspsim.cli import main

sys.exit(main())
