"""Exploring an unknown environment (Bhattacharya et al. 2014, Sec. 4.2): what each robot
believes of the map, built from its lidar and shared with the team, and the entropy of that
belief that drives the coordinated exploration."""
