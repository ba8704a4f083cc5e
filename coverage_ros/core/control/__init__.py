"""One robot's control, independent of ROS: the coverage controller (:mod:`.controller`), its
table of neighbours (:mod:`.neighbours`), path planning (:mod:`.planning`), path tracking
(:mod:`.tracking`) and the safety filter (:mod:`.safety`)."""
