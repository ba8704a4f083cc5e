"""Lock-step simulation across processes, independent of ROS: the world's barrier
(:mod:`.barrier`: whom it waits for, when the next tick may go) and a member's inbox
(:mod:`.inbox`: stamped inputs held until the tick they belong to, and what is still missing).

The protocol (README "Lock-step simulation"): the world publishes tick ``k`` after everything
it publishes for that instant (poses, scans, status); every member answers DONE for ``k``
after it has used exactly the inputs of ``k`` - its pose and scans stamped up to ``t_k``, every
other robot's state stamped ``t_{k-1}`` - published its own state stamped ``t_k`` and sent its
command; the world then applies the commands and steps to ``k + 1``. Times are integer
nanoseconds of sim time, so stamps compare exactly.
"""

from coverage_ros.core.lockstep.barrier import Barrier, Member, TickPlan, observer, robot
from coverage_ros.core.lockstep.inbox import Inbox, Tick, TickInputs, ticks_per

__all__ = ["Barrier", "Inbox", "Member", "Tick", "TickInputs", "TickPlan", "observer", "robot",
           "ticks_per"]
