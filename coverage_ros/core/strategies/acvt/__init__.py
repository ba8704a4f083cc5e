"""Adaptive centroidal Voronoi tessellation with agent dropout and reinsertion (Lee & Lee,
"Adaptive centroidal Voronoi tessellation with agent dropout and reinsertion for multi-agent
non-convex area coverage", IEEE Access 2024).

* :mod:`.strategy` - the ``acvt`` strategy, decentralized;
* :mod:`.params` - its settings and the dropout, relocation and cell settings they give;
* :mod:`.dropout` - the paper's centralized alpha-CVT (Algorithms 1 and 2);
* :mod:`.relocation` - a light agent reinserted where the team's metric is predicted to
  fall, and :mod:`.prediction` - the team's iCVT + projection run forward and its metric;
* :mod:`.cells` - the paper's cells on the grid (plain, visibility, shape constraint,
  heterogeneous reach), masses, centroids, projection and metrics.
"""
