"""Triangle / triangle contact for the leaves of the box hierarchies.

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
"""
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
