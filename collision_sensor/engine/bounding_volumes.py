"""Bounding volumes of point sets: oriented boxes (paper sec. 3, Wu's principal axes) and spheres.

Box convention (every fit here returns it, and :mod:`collision_sensor.engine.obb_tree` relies on
it)::

    center : (3,) float64     the box's mid point (not the mean of the points)
    axes   : (3, 3) float64   axes[:, k] is the k-th box axis: a right-handed orthonormal frame
                              (det = +1; axes[:, 2] = axes[:, 0] x axes[:, 1], never an
                              eigenvector's own sign), axes[:, 0] the direction of largest
                              variance, axes[:, 1] the next (variance of the points; for
                              fit_obb_hull_pca, of the convex hull's surface)
    half   : (3,) float64     half extents along those axes, >= 0 (0 for flat input)

so a point x is inside iff ``|axes.T @ (x - center)| <= half`` componentwise. The extents come
from the minimum and maximum of the points projected on the axes, so every point is inside up to
rounding (about 1e-16 of the coordinates; the box tests' tolerance covers it many times over).
Signs are made deterministic: the largest-magnitude component of axes[:, 0] and of axes[:, 1]
is positive.

Degenerate input is handled on purpose: one point gives a point box (half = 0, axes = the
identity), two points or collinear points a segment box, coplanar points a flat box; repeated
points are harmless; NaN, infinity or no points raise
:class:`~collision_sensor.errors.EngineInputError` (a ValueError).
"""
import numpy as np

from collision_sensor.engine.compiled import engine
from collision_sensor.engine.tolerances import RANK_EPS_REL
from collision_sensor.errors import EngineInputError

OBB_PCA, OBB_HULL_PCA, OBB_MIN_VOLUME, OBB_REFINED = 0, 1, 2, 3


# The kernels below are C++ (cpp/bounding_volumes.cpp, bound as collision_sensor.engine._engine);
# these wrappers keep their Python names and state each contract.


def obb_volume(half) -> float:
    """Return the volume 8 hx hy hz of a box with half extents ``half`` (3,)."""
    return engine.obb_volume(half)


def sphere_volume(r: float) -> float:
    """Return the volume 4/3 pi r^3 of a sphere of radius ``r``."""
    return engine.sphere_volume(r)


def _check_points(points):
    """Raise EngineInputError if ``points`` (n, 3) is empty or holds NaN or infinity."""
    engine.check_points(points)


def _frame_from_eigenvectors(V, order):
    """Return the box frame (3, 3) built from columns ``order[0]``, ``order[1]`` of ``V``.

    Contract in plain Python::

        a0 = V[:, order[0]] / |V[:, order[0]]|
        a1 = V[:, order[1]] - (V[:, order[1]] . a0) a0;  a1 /= |a1|      # Gram-Schmidt
        a0, a1 each negated if its largest-magnitude component is negative
        axes = [a0, a1, a0 x a1] as columns: right-handed, whatever the eigen solver returned

    :param V: (3, 3) float64, candidate axes as columns.
    :param order: (3,) int64, column indices; only the first two are used.
    """
    return engine.frame_from_eigenvectors(V, order)


def principal_frame(C):
    """Return the box frame (3, 3) of a symmetric covariance C: eigenvectors, largest first.

    The eigenvectors of C (cyclic Jacobi, cpp/bounding_volumes.cpp) are sorted by decreasing
    eigenvalue and passed through :func:`_frame_from_eigenvectors`; for repeated eigenvalues
    any orthonormal basis of the eigenspace is correct. A zero C (one point, or all points
    equal) gives the identity.
    """
    return engine.principal_frame(C)


def box_on_axes(points, axes):
    """Return (center, half) of the smallest box with the given axes containing ``points``.

    :param points: (n, 3) float64, n >= 1.
    :param axes: (3, 3) float64, axes[:, k] the box axes.
    :return: center (3,) the box's mid point, half (3,) its half extents.
    """
    return engine.box_on_axes(points, axes)


def covariance(points):
    """Return the (3, 3) covariance of ``points`` (n, 3) (two-pass: mean first, 1/n)."""
    return engine.covariance(points)


def fit_obb_pca(points):
    """Fit an oriented box by principal axes (Wu 1992, paper sec. 3): the default, O(n).

    The covariance of the points gives the axes (its eigenvectors, largest variance first);
    the extents are the min/max of the points projected on them. Contract in plain Python::

        axes = principal_frame(covariance(points)); center, half = box_on_axes(points, axes)

    :param points: (n, 3) float64, n >= 1, finite.
    :return: (center (3,), axes (3, 3), half (3,)) in the module's convention.
    :raises EngineInputError: no points, NaN / infinity in them, or not of shape (n, 3).
    """
    return engine.fit_obb_pca(points)


def fit_obb_refined(points):
    """Fit an oriented box by principal axes, then tighten it around each of them, O(n log n).

    With principal axis k kept, the other two are turned to the smallest-area rectangle
    around the points projected on the plane they span (a side lies on an edge of the
    projection's convex hull, Freeman & Shapira 1975); of the principal-axes box and these
    three, the one of least volume (then surface) is kept, and the same is done around its
    axes, up to three rounds while it shrinks; its axes are re-ordered by decreasing variance.
    The axes are chosen on at most 256 of the points plus the 14 extremes along the principal
    axes and box diagonals, every edge of their hull tried (rotating calipers); the extents
    come from every point, so the box always contains them. One triangle: the smallest box
    with a side along one of its edges; 4 to 48 points: the principal box. Tree builds use it
    for the top of each tree (nodes over 1/64 of the mesh), which keeps their time near the
    vertex fit's and gets most of :func:`fit_obb_min_volume`'s
    tightness (``docs/performance.md``, scenario 5: bounding-volume fits).

    :param points: (n, 3) float64, n >= 1, finite.
    :return: (center (3,), axes (3, 3), half (3,)) in the module's convention.
    :raises EngineInputError: no points, NaN / infinity in them, or not of shape (n, 3).
    """
    return engine.fit_obb_refined(_as_points(points))


def _as_points(points, faces=None):
    pts = np.ascontiguousarray(np.asarray(points, dtype=np.float64))
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise EngineInputError(f'bounding volume: points must have shape (n, 3), got {pts.shape}')
    if faces is not None:
        faces = np.asarray(faces)
        if faces.size:
            if faces.min() < 0 or faces.max() >= len(pts):
                raise EngineInputError(
                    f'bounding volume: faces index vertices outside 0..{len(pts) - 1}')
            pts = np.ascontiguousarray(pts[np.unique(faces)])
    _check_points(pts)
    return pts


def _subspace(points):
    """Return (mean, basis (3, 3) rows = principal directions, rank) of a point set."""
    mean = points.mean(axis=0)
    _, s, vt = np.linalg.svd(points - mean, full_matrices=True)
    s = np.concatenate([s, np.zeros(3 - len(s))])
    rank = int(np.sum(s > RANK_EPS_REL * s[0])) if s[0] > 0 else 0
    return mean, vt, rank


def _surface_covariance(tris):
    """Return the area-weighted covariance of the surface of triangles (m, 3, 3).

    Gottschalk, Lin & Manocha (1996): for a triangle (p, q, r) of area A and centroid c, the
    second moment of its area is A / 12 (9 c c^T + p p^T + q q^T + r r^T); summed, divided by the
    total area, minus the mean outer product. Uniform in area, so vertex density does not bias
    the axes.
    """
    p, q, r = tris[:, 0], tris[:, 1], tris[:, 2]
    area = 0.5 * np.linalg.norm(np.cross(q - p, r - p), axis=1)
    total = area.sum()
    if not total > 0.0:
        return None
    c = (p + q + r) / 3.0
    mean = (area[:, None] * c).sum(axis=0) / total
    # Centre first (the covariance is translation invariant) for precision.
    p, q, r, c = p - mean, q - mean, r - mean, c - mean
    M = np.einsum('i,ij,ik->jk', area / 12.0, 9 * c, c)
    for v in (p, q, r):
        M += np.einsum('i,ij,ik->jk', area / 12.0, v, v)
    return M / total


def fit_obb_hull_pca(vertices, faces=None):
    """Fit an oriented box by the principal axes of the convex hull's surface (area-weighted).

    The robust variant of OBB-tree builders: the covariance of the hull surface, not of the
    vertices, so clustered vertices do not tilt the box. Flat input uses the area of its planar
    hull polygon; collinear input (or fewer than 3 distinct points) falls back to
    :func:`fit_obb_pca`, which is exact there.

    :param vertices: (n, 3) float points.
    :param faces: optional (m, 3) int; if given, only the vertices the faces use are fitted.
    :return: (center (3,), axes (3, 3), half (3,)) in the module's convention.
    :raises EngineInputError: no points, NaN / infinity, or faces out of range.
    """
    from scipy.spatial import ConvexHull

    pts = _as_points(vertices, faces)
    mean, basis, rank = _subspace(pts)
    C = None
    if rank == 3:
        hull = ConvexHull(pts)
        C = _surface_covariance(pts[hull.simplices])
    elif rank == 2:
        uv = (pts - mean) @ basis[:2].T
        ring = ConvexHull(uv).vertices                   # counter-clockwise polygon
        poly = pts[ring]
        fan = np.stack([np.repeat(poly[:1], len(poly) - 2, axis=0), poly[1:-1], poly[2:]], axis=1)
        C = _surface_covariance(fan)
    if C is None:
        return fit_obb_pca(pts)
    axes = principal_frame(C)
    center, half = box_on_axes(pts, axes)
    return center, axes, half


def _canonical(points, axes):
    """Re-order box axes by decreasing variance of the points, right-handed, signs fixed."""
    var = np.var((points - points.mean(axis=0)) @ axes, axis=0)
    order = np.argsort(-var, kind='stable')
    axes = _frame_from_eigenvectors(np.ascontiguousarray(axes), order.astype(np.int64))
    center, half = box_on_axes(points, axes)
    return center, axes, half


def fit_obb_min_volume(points):
    """Fit a near-minimum-volume oriented box (trimesh.bounds.oriented_bounds), slow.

    trimesh searches the hull's face directions with a minimum-area rectangle for each; the
    result is returned in this module's convention, and compared with the two principal-axis
    boxes: the smallest of the three is returned, so this fit is never larger than
    :func:`fit_obb_pca` or :func:`fit_obb_hull_pca`. Flat input gets trimesh's minimum-area
    rectangle in its plane; collinear input the exact segment box.

    :param points: (n, 3) float points.
    :return: (center (3,), axes (3, 3), half (3,)) in the module's convention.
    :raises EngineInputError: no points, or NaN / infinity in them.
    """
    from trimesh import bounds

    pts = _as_points(points)
    mean, basis, rank = _subspace(pts)
    if rank <= 1:
        return fit_obb_pca(pts)
    if rank == 2:
        uv = (pts - mean) @ basis[:2].T
        T2, _ = bounds.oriented_bounds_2D(uv)
        # T2 maps the 2-D points into the rectangle's frame: its rows are the rectangle axes.
        axes = np.empty((3, 3))
        axes[:, 0] = basis[:2].T @ T2[0, :2]
        axes[:, 1] = basis[:2].T @ T2[1, :2]
        axes[:, 2] = basis[2]
        return _canonical(pts, axes)
    to_origin, _ = bounds.oriented_bounds(pts)
    # to_origin maps world points into the box frame: its rotation's rows are the box axes.
    candidates = [_canonical(pts, to_origin[:3, :3].T.copy()), fit_obb_pca(pts),
                  fit_obb_hull_pca(pts)]
    return min(candidates, key=lambda box: obb_volume(box[2]))


def fit_obb(points, method=OBB_PCA, faces=None):
    """Fit an oriented box to ``points`` by ``method`` (OBB_PCA, OBB_HULL_PCA, OBB_MIN_VOLUME,
    OBB_REFINED).

    :param points: (n, 3) float points.
    :param method: one of OBB_PCA (0), OBB_HULL_PCA (1), OBB_MIN_VOLUME (2), OBB_REFINED (3).
    :param faces: optional (m, 3) int triangles over ``points``; only OBB_HULL_PCA uses them
        (to drop unreferenced vertices).
    :return: (center (3,), axes (3, 3), half (3,)) in the module's convention.
    :raises EngineInputError: unknown method, no points, or NaN / infinity in them.
    """
    if method == OBB_PCA:
        return fit_obb_pca(_as_points(points))
    if method == OBB_HULL_PCA:
        return fit_obb_hull_pca(points, faces)
    if method == OBB_MIN_VOLUME:
        return fit_obb_min_volume(points)
    if method == OBB_REFINED:
        return fit_obb_refined(points)
    raise EngineInputError(f'fit_obb: unknown method {method!r}; use OBB_PCA (0), OBB_HULL_PCA '
                           '(1), OBB_MIN_VOLUME (2) or OBB_REFINED (3)')


def ritter_sphere(points):
    """Return (center (3,), radius) of a near-minimal bounding sphere (Ritter 1990), O(n).

    Ritter: from an arbitrary point find the farthest point y, from y the farthest z; start
    with the sphere on the diameter yz and grow it, in one pass, just enough to take in each
    point outside it. The radius is then set to the largest distance from the final centre (so
    containment is exact up to rounding), and if the axis-aligned box's circumscribed sphere is
    smaller, that is returned instead (Ritter's sphere is ~5% above the optimum, which can
    exceed the box's half diagonal on box-filling clouds).

    :param points: (n, 3) float64, n >= 1, finite.
    :return: (center (3,), radius float).
    :raises EngineInputError: no points, or NaN / infinity in them.
    """
    return engine.ritter_sphere(points)
