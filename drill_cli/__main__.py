"""``python -m drill_cli <command>``: the same as ``drill-env <command>``."""

import sys

from drill_cli.main import main

sys.exit(main())
