"""The uncoordinated frontier-exploration baseline (explore_lite, Hörner 2016; m-explore-ros2):
:mod:`.frontiers` finds and ranks frontiers, :mod:`.strategy` picks goals as explore_lite does."""
