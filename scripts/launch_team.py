#!/usr/bin/env python3
"""The team launcher as a script: the same as ``coverage-team`` (see README "Running a team").

    .venv/bin/python scripts/launch_team.py --robots 6 --world office --record
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from coverage_ros.cli.team import main

if __name__ == "__main__":
    sys.exit(main())
