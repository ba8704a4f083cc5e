"""``python -m coverage_ros.cli.team``: the launcher."""

import sys

from coverage_ros.cli.team.launch import main

sys.exit(main())
