"""The algorithms, in pure numpy/scipy (never rclpy, pymunk or rerun; a test checks every
module).

* :mod:`.world` - what the world is: maps, obstacles, densities, robots, where they may stand;
* :mod:`.geodesic` - the geodesic (power) Voronoi machinery of Bhattacharya et al. (2014):
  metric grid graphs, the coverage domain, local searches, tessellations, tangents, charts of
  curved surfaces, the slow reference implementations; and the Euclidean cells of classic Lloyd;
* :mod:`.strategies` - one robot's coverage brain behind one interface, one module or package
  per method, selected by name through the registry;
* :mod:`.control` - one robot's controller: neighbours, path planning, tracking, safety;
* :mod:`.offline` - a team run centrally (``coverage-plan``), with simulated scans;
* :mod:`.metrics` - coverage cost, mass deviation, sensor coverage;
* :mod:`.geometry` - small vectorized 2-D helpers.
"""
