"""Visualisation outputs (PNG images, rerun recordings). Algorithms never import this."""
