"""coverage-team: run a coverage team - the world node and the robots' processes - and score it.

One module per job: :mod:`.options` (the command line to a checked run configuration),
:mod:`.members` (the team: who, where, with which body), :mod:`.robots` (the robots' processes
and parameters), :mod:`.network` (robots on other hosts, the discovery server),
:mod:`.processes` (child processes and their stopping), :mod:`.domains` (a free ROS domain),
:mod:`.launch` (starting and stopping a run in order), :mod:`.monitor` (the node that follows
and scores the run; in lock-step with :mod:`.lockstep`, exploring with :mod:`.exploration`) and
:mod:`.summary` (``summary.json`` and the table).
"""

from coverage_ros.cli.team.launch import main

__all__ = ["main"]
