"""Distances with nearest points, for :meth:`CollisionChecker.proximity` (issue 15).

Contract in plain Python::

    d, x, y = triangle_distance(P, Q)
    d == min(norm(p - q) for p in P for q in Q)     # over the closed triangles' points
    norm(x - y) == d; x in P; y in Q                # a nearest pair (x == y when they meet)

    proximity: for each checked pair (a, b), with padding(x) the body's padding (0 for none),
    surfaces = min(triangle_distance(P, Q)[0] for P in triangles(a) for Q in triangles(b))
    distance(a, b) == surfaces - padding(a) - padding(b)
    reported iff distance(a, b) < max_distance; <= 0 iff check() says the pair is in contact
    (no penetration depth: 0 for surfaces that meet, minus the paddings), with one point in
    both padded bodies; apart, the nearest points of the padded bodies

``P, Q : (3, 3) float64``, rows the vertices, both in the same frame. The nearest points of two
disjoint triangles are a vertex of one and its foot on the other, or the nearest points of an
edge of each; crossing triangles have an edge through the other's face. A triangle thinner than
the contact tolerance (its sine below ``TRIANGLE_EPS_REL``) is its three edges.

The kernels are C++: the triangle distance with Gottschalk's early exit (PQP's TriDist,
``cpp/triangle_distance.hpp``), and the traversal of two OBB trees (``cpp/distance.hpp``) that
visits the nearer child pair first and prunes node pairs whose lower bound reaches
``max_distance`` or the best distance found. Two bounds: each node's extent along the
direction of the nearest points found so far (one subtraction per node pair, tight for bodies
far apart), and, where that one falls short, the boxes' gap along an axis aimed at their own
nearest points by alternating projection. Each pair starts from the triangles nearest at the
previous call, so under coherent motion the traversal mostly proves a known answer.
"""
from typing import Tuple

import numpy as np

from collision_sensor.engine.compiled import engine


def triangle_distance(P, Q) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return the distances between triangles and a nearest pair of points on each.

    :param P: (n, 3, 3) float64, rows the vertices of the first triangles (or (3, 3)).
    :param Q: (n, 3, 3) float64, the second triangles, in the same frame (or (3, 3)).
    :return: ``d`` (n,) distances, ``x`` (n, 3) points on P, ``y`` (n, 3) points on Q.
    """
    P = np.ascontiguousarray(P, dtype=np.float64).reshape(-1, 3, 3)
    Q = np.ascontiguousarray(Q, dtype=np.float64).reshape(-1, 3, 3)
    return engine.triangle_distance(P, Q)
