"""Geodesic power Voronoi coverage on metric grid graphs (Bhattacharya, Michael & Kumar,
"Multi-robot coverage and exploration on Riemannian manifolds with boundaries", IJRR 2014).

* :mod:`.graph` - grid graphs whose edge costs are metric lengths;
* :mod:`.domain` - the coverage domain (configuration space, metric, density, virtual sources);
* :mod:`.local_search` - the pruned, cached search region of one robot's update;
* :mod:`.tessellation` - cells, the generalized Lloyd control, the centralized tessellation;
* :mod:`.descent` - turning the control into a reachable goal;
* :mod:`.tangents` - geodesic tangents and line of sight;
* :mod:`.charts` - curved surfaces (sphere, torus) through coordinate charts;
* :mod:`.reference` - slow, obvious implementations the fast ones are tested against;
* :mod:`.euclidean` - the Euclidean (power) Voronoi cells of classic Lloyd on the same domain.
"""
