"""Adaptive centroidal Voronoi tessellation with agent dropout and reinsertion (Lee & Lee,
"Adaptive centroidal Voronoi tessellation with agent dropout and reinsertion for multi-agent
non-convex area coverage", IEEE Access 2024).

* :mod:`.strategy` - the ``acvt`` strategy, decentralized;
* :mod:`.dropout` - the paper's centralized alpha-CVT (Algorithms 1 and 2);
* :mod:`.cells` - the paper's cells on the grid (plain, visibility, shape constraint,
  heterogeneous reach), masses, centroids, projection and metrics.
"""
