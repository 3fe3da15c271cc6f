"""The compiled engine's leaf kernels called one pair at a time, with their contracts in plain
Python: only the tests call them so (the engine runs them inside its queries).

Triangle / triangle contact (``cpp/triangle_test.hpp``)
-------------------------------------------------------
Contract in plain Python::

    triangles_intersect(P, Q) == (distance(P, Q) <= TRIANGLE_EPS_REL * m)

``P, Q : (3, 3) float64``, rows the vertices, both in the same frame; ``distance`` is the
Euclidean distance between the closed triangles (0 when they cross or touch), ``m`` the largest
absolute coordinate of the six vertices. So touching counts as contact, and so does a gap below
the tolerance (about 1e-12 of the coordinates, the scale of their own rounding). Coplanar
triangles are decided by the same rule (overlapping, touching at an edge or a vertex, or one
inside the other: distance 0). A zero-area triangle is the segment or point it is; a sliver
thinner than half the tolerance is treated as its three edges, which moves it by less than
half the tolerance. Input with a NaN or an infinity answers True (err toward contact).

The test is C++ (``cpp/triangle_test.hpp``); :func:`triangles_intersect` calls it.

Why a distance rule rather than orientation predicates alone (Moeller, Guigue-Devillers): in
float64, signs of near-zero determinants are noise, so "touching" has no stable answer; a
distance against a tolerance is continuous in the input, so touching, coplanar and degenerate
cases all get the same reproducible answer and the branches stay few. Cost: a plane test
rejects most pairs with 2 cross products, an edge piercing the other triangle settles most
contacts, and a gap along one of the nine edge-edge axes (beyond its rounding) most near
misses; only pairs near touching pay for up to 6 point-triangle and 9 segment-segment
distances, with an early exit at the first contact.

Distances with nearest points (``cpp/triangle_distance.hpp``, ``cpp/distance.hpp``)
-------------------------------------------------------------------------------------
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


def triangles_intersect(P, Q):
    """Return True iff the closed triangles P and Q touch or cross (see the module contract).

    :param P: (3, 3) float64, rows the vertices of the first triangle; or (n, 3, 3).
    :param Q: (3, 3) float64, rows the vertices of the second, in the same frame; or (n, 3, 3).
    :return: True iff their distance is at most ``TRIANGLE_EPS_REL`` times the largest
        absolute coordinate (touching counts as contact); (n,) bool for n pairs.
    """
    return engine.triangles_intersect(np.ascontiguousarray(P, dtype=np.float64),
                                      np.ascontiguousarray(Q, dtype=np.float64))


def triangle_distance(P, Q) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return the distances between triangles and a nearest pair of points on each.

    :param P: (n, 3, 3) float64, rows the vertices of the first triangles (or (3, 3)).
    :param Q: (n, 3, 3) float64, the second triangles, in the same frame (or (3, 3)).
    :return: ``d`` (n,) distances, ``x`` (n, 3) points on P, ``y`` (n, 3) points on Q.
    """
    P = np.ascontiguousarray(P, dtype=np.float64).reshape(-1, 3, 3)
    Q = np.ascontiguousarray(Q, dtype=np.float64).reshape(-1, 3, 3)
    return engine.triangle_distance(P, Q)
