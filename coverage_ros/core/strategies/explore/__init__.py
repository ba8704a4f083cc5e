"""Coordinated exploration of unknown maps with the entropy-weighted geodesic metric
(Bhattacharya et al. 2014, Sec. 4.2): the ``geodesic`` strategy when the team explores."""
