"""``python -m vehicle`` runs the ``vehicle`` command."""

import sys

from vehicle.app.cli import main

sys.exit(main())
