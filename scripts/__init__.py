"""Maintainer scripts: they write files of the source tree (not installed).

- ``python scripts/demo_cell.py``: the demo cell's meshes, robots, scenes and sequences
  (``config/``, ``meshes/demo_cell/``).
"""
