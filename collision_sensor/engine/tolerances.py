"""Every numerical tolerance of the geometric kernels, explained in one place.

The engine's tolerances and limits are its own (``cpp/tolerances.hpp``, which explains each):
their values are read from the extension here, and the geometric ones stated and explained
below. Each constant is dimensionless and multiplies a
length scale named next to it, so every test reads the same whether a robot is measured in metres
or millimetres. All of them make the sensor err toward "contact": a tolerance only ever turns a
near miss into a reported contact, never a contact into a miss.

Relations to keep when changing a value
---------------------------------------
- ``BOX_EPS_REL * BOX_EPS_PARALLEL`` must stay far above float64 rounding (2.2e-16): it is
  the floor that keeps a separating axis made from two almost parallel edges (whose direction
  is rounding noise) from ever declaring separation.
- ``BOX_EPS_REL`` must stay far below any gap that matters: a box test keeps a pair whose gap
  is below ``BOX_EPS_REL * (sum of the six half extents)``; 1e-9 of the boxes' size is
  below every mesh's own precision.
- Bounding-volume fits are not padded: the boxes contain their points up to rounding (about
  1e-16 of the coordinates), which ``BOX_EPS_REL`` covers many times over.
"""
from collision_sensor.engine.compiled import engine

#: Box tests (``box_test.py``, ``cpp/box_test.hpp``): boxes A and B are separated only if, along
#: one candidate axis L, the gap between their projections exceeds ``BOX_EPS_REL * s * (1 +
#: BOX_EPS_PARALLEL / |L|)``, where ``s`` is the sum of the six half extents and ``|L|`` the length
#: of the unnormalised axis (1 for a face normal, ``sin`` of the angle between the two edges for an
#: edge-edge axis ``a_i x b_j``). Touching (gap 0) therefore always counts as overlapping.
BOX_EPS_REL = engine.BOX_EPS_REL

#: Box tests: floor for nearly parallel edge pairs (see ``BOX_EPS_REL``). It plays the part
#: of the epsilon coal adds to ``|R|``: the closer the two edges are to parallel, the larger
#: the gap an edge-edge axis needs to count, so rounding noise in a near-zero cross product
#: can never separate. Near-parallel configurations are still decided by the face axes.
BOX_EPS_PARALLEL = engine.BOX_EPS_PARALLEL

#: Triangle test (``cpp/triangle_test.hpp``): two triangles are in contact iff the float64
#: Euclidean distance between them is at most ``TRIANGLE_EPS_REL * m``, where ``m`` is the largest
#: absolute coordinate of the six vertices (the scale of the rounding error of every coordinate
#: difference the test forms). Touching (distance 0) is contact.
TRIANGLE_EPS_REL = engine.TRIANGLE_EPS_REL

#: Bounding volumes (``bounding_volumes.py``, this package's own): a point set whose spread across
#: its ``k``-th principal direction is at most ``RANK_EPS_REL`` times its largest spread is treated
#: as flat in that direction (decides coplanar / collinear input for the convex-hull fits).
RANK_EPS_REL = 1e-12

#: Sphere pre-test of the traversal (``cpp/traversal.hpp``): two boxes are skipped without the box
#: test only if the spheres around them (centre = box centre, radius = |half extents|) are apart by
#: more than ``SPHERE_EPS_REL`` of the sum of their radii. The spheres contain the boxes, so this
#: only ever skips pairs the box test would also separate.
SPHERE_EPS_REL = engine.SPHERE_EPS_REL

#: Closed meshes taken for hulls (``cpp/model.cpp``): no vertex beyond a face plane by more
#: than this fraction of the mesh's extent.
HULL_FLAT_REL = engine.HULL_FLAT_REL

#: A bound computed in a few float64 operations is widened by this fraction of its terms.
BOUND_ROUNDING_REL = engine.BOUND_ROUNDING_REL

#: The incremental query (``cpp/planning.hpp``): a pair's clearance is rounded down by this
#: fraction of its coordinate scale; its running travel sum is recomputed once it reaches
#: ``TRAVEL_GUARD`` of the clearance; a front's node pair stays untested while its margin
#: exceeds ``FRONT_GUARD_REL`` of itself; a pair keeps a front while its clearance is at most
#: ``FRONT_GAP_REL`` of its size.
CLEARANCE_EPS_REL = engine.CLEARANCE_EPS_REL
TRAVEL_GUARD = engine.TRAVEL_GUARD
FRONT_GUARD_REL = engine.FRONT_GUARD_REL
FRONT_GAP_REL = engine.FRONT_GAP_REL

#: Motion checks (``cpp/motion.hpp``; :mod:`collision_sensor.engine.motion`): a first contact is
#: within ``MOTION_TOUCH_TOLERANCE`` (m) of contact; every bound is widened by
#: ``MOTION_BOUND_REL``; a ray-cast sweep stops within ``SWEEP_EPS`` (m); slerp between
#: quaternions less than ``SLERP_HALF_ANGLE_MIN`` (rad, half the angle) apart is their chord.
MOTION_TOUCH_TOLERANCE = engine.MOTION_TOUCH_TOLERANCE
MOTION_BOUND_REL = engine.MOTION_BOUND_REL
SWEEP_EPS = engine.SWEEP_EPS
SLERP_HALF_ANGLE_MIN = engine.SLERP_HALF_ANGLE_MIN

#: The values the engine takes: joint translations within ``PRISMATIC_VALUE_MAX`` (m), a
#: quaternion (a floating joint's, a scene pose's) of norm at least ``QUATERNION_NORM_MIN``,
#: scene poses within ``MAX_COORDINATE`` (m) orthonormal to ``ROTATION_TOLERANCE``, a cloud
#: pair's clearance at most ``MAX_CLOUD_CLEARANCE`` (m), at most ``MAX_THREADS`` threads.
PRISMATIC_VALUE_MAX = engine.PRISMATIC_VALUE_MAX
QUATERNION_NORM_MIN = engine.QUATERNION_NORM_MIN
MAX_COORDINATE = engine.MAX_COORDINATE
ROTATION_TOLERANCE = engine.ROTATION_TOLERANCE
MAX_CLOUD_CLEARANCE = engine.MAX_CLOUD_CLEARANCE
MAX_THREADS = engine.MAX_THREADS
