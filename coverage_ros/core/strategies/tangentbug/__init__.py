"""Lloyd on virtual generators with TangentBug to the real targets (Breitenmoser, Schwager,
Metzger, Siegwart & Rus, "Voronoi coverage of non-convex environments with a group of networked
robots", ICRA 2010).

* :mod:`.strategy` - the ``tangentbug`` strategy (Algorithms 1 and 2);
* :mod:`.bug` - TangentBug on a planar scan, with the paper's reachability test and projection;
* :mod:`.boundary` - one run along an obstacle boundary: distance, closest point, loop test;
* :mod:`.steering` - the unicycle command that drives TangentBug's heading, with its brake;
* :mod:`.scan_geometry` - geometry of range scans the planner works on.
"""
