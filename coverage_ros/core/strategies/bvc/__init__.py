"""Buffered Voronoi cells from lidar points with a deadlock-aware guided map (Wang, Xu, Gao,
Chen, Zhang, Wang, Ding & Chen, "Sensor-based multi-agent coverage control with spatial
separation in unstructured environments", 2024).

* :mod:`.strategy` - the ``bvc`` strategy;
* :mod:`.cells` - buffered Voronoi cells from raw range points (Sec. IV-A/B);
* :mod:`.memory` - what a robot remembers of its scans: hits and cells seen free (Sec. IV-C);
* :mod:`.guided_map` - the guided map's local window, goal and navigation function;
* :mod:`.guide` - the guided map's goal and density (Eq. 8) for one robot;
* :mod:`.peaks` - peaks of the density that no robot attends.
"""
