"""Bounding volumes of point sets: oriented boxes (paper sec. 3, Wu's principal axes) and spheres.

Box convention (every fit here returns it, and :mod:`collision_sensor.obb_tree` relies on it)::

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
points are harmless; NaN, infinity or no points raise ValueError.
"""
import math

import numba
import numpy as np

from collision_sensor.kernel_cache import bind_to_kernel_sources
from collision_sensor.tolerances import RANK_EPS_REL

OBB_PCA, OBB_HULL_PCA, OBB_MIN_VOLUME = 0, 1, 2


@numba.njit(cache=True)
def obb_volume(half):
    """Return the volume 8 hx hy hz of a box with half extents ``half`` (3,)."""
    return 8.0 * half[0] * half[1] * half[2]


@numba.njit(cache=True)
def sphere_volume(r):
    """Return the volume 4/3 pi r^3 of a sphere of radius ``r``."""
    return 4.0 / 3.0 * math.pi * r * r * r


@numba.njit(cache=True)
def _check_points(points):
    if points.shape[0] == 0:
        raise ValueError('bounding volume: no points; a bounding volume needs at least one point')
    for i in range(points.shape[0]):
        for k in range(3):
            x = points[i, k]
            if not (abs(x) < math.inf):
                raise ValueError('bounding volume: points contain NaN or infinity; '
                                 'check the mesh or the transform that produced them')


@numba.njit(cache=True)
def _frame_from_eigenvectors(V, order):
    # Columns V[:, order[0]], V[:, order[1]] re-orthonormalised (Gram-Schmidt), signs fixed,
    # third axis the cross product: right-handed by construction, whatever LAPACK returned.
    axes = np.empty((3, 3))
    a0 = V[:, order[0]].copy()
    a0 /= math.sqrt(a0[0] * a0[0] + a0[1] * a0[1] + a0[2] * a0[2])
    a1 = V[:, order[1]].copy()
    d = a1[0] * a0[0] + a1[1] * a0[1] + a1[2] * a0[2]
    a1 -= d * a0
    a1 /= math.sqrt(a1[0] * a1[0] + a1[1] * a1[1] + a1[2] * a1[2])
    for a in (a0, a1):
        k = 0
        for m in range(1, 3):
            if abs(a[m]) > abs(a[k]):
                k = m
        if a[k] < 0.0:
            a *= -1.0
    axes[:, 0] = a0
    axes[:, 1] = a1
    axes[0, 2] = a0[1] * a1[2] - a0[2] * a1[1]
    axes[1, 2] = a0[2] * a1[0] - a0[0] * a1[2]
    axes[2, 2] = a0[0] * a1[1] - a0[1] * a1[0]
    return axes


@numba.njit(cache=True)
def principal_frame(C):
    """Return the box frame (3, 3) of a symmetric covariance C: eigenvectors, largest first.

    The eigenvectors of C (LAPACK, ascending eigenvalues) are sorted by decreasing eigenvalue;
    for repeated eigenvalues any orthonormal basis of the eigenspace is correct. A zero C (one
    point, or all points equal) gives the identity.
    """
    if C[0, 0] == 0.0 and C[1, 1] == 0.0 and C[2, 2] == 0.0:
        return np.eye(3)
    w, V = np.linalg.eigh(C)
    order = np.argsort(-w)
    return _frame_from_eigenvectors(V, order)


@numba.njit(cache=True)
def box_on_axes(points, axes):
    """Return (center, half) of the smallest box with the given axes containing ``points``.

    :param points: (n, 3) float64.
    :param axes: (3, 3) float64, axes[:, k] the box axes.
    :return: center (3,) the box's mid point, half (3,) its half extents.
    """
    n = points.shape[0]
    # Project about the first point so that far-from-origin clouds keep their precision.
    o0, o1, o2 = points[0, 0], points[0, 1], points[0, 2]
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for i in range(n):
        x0, x1, x2 = points[i, 0] - o0, points[i, 1] - o1, points[i, 2] - o2
        for k in range(3):
            s = x0 * axes[0, k] + x1 * axes[1, k] + x2 * axes[2, k]
            if s < lo[k]:
                lo[k] = s
            if s > hi[k]:
                hi[k] = s
    center = np.empty(3)
    half = np.empty(3)
    mid = np.empty(3)
    for k in range(3):
        half[k] = 0.5 * (hi[k] - lo[k])
        mid[k] = 0.5 * (hi[k] + lo[k])
    center[0] = o0 + axes[0, 0] * mid[0] + axes[0, 1] * mid[1] + axes[0, 2] * mid[2]
    center[1] = o1 + axes[1, 0] * mid[0] + axes[1, 1] * mid[1] + axes[1, 2] * mid[2]
    center[2] = o2 + axes[2, 0] * mid[0] + axes[2, 1] * mid[1] + axes[2, 2] * mid[2]
    return center, half


@numba.njit(cache=True)
def covariance(points):
    """Return the (3, 3) covariance of ``points`` (n, 3) (two-pass: mean first)."""
    n = points.shape[0]
    m0 = m1 = m2 = 0.0
    for i in range(n):
        m0 += points[i, 0]
        m1 += points[i, 1]
        m2 += points[i, 2]
    m0 /= n
    m1 /= n
    m2 /= n
    C = np.zeros((3, 3))
    for i in range(n):
        x0, x1, x2 = points[i, 0] - m0, points[i, 1] - m1, points[i, 2] - m2
        C[0, 0] += x0 * x0
        C[0, 1] += x0 * x1
        C[0, 2] += x0 * x2
        C[1, 1] += x1 * x1
        C[1, 2] += x1 * x2
        C[2, 2] += x2 * x2
    C[1, 0] = C[0, 1]
    C[2, 0] = C[0, 2]
    C[2, 1] = C[1, 2]
    return C / n


@numba.njit(cache=True)
def fit_obb_pca(points):
    """Fit an oriented box by principal axes (Wu 1992, paper sec. 3): the default, O(n).

    The covariance of the points gives the axes (its eigenvectors, largest variance first);
    the extents are the min/max of the points projected on them. Callable from compiled code.

    :param points: (n, 3) float64, n >= 1, finite.
    :return: (center (3,), axes (3, 3), half (3,)) in the module's convention.
    :raises ValueError: no points, or NaN / infinity in them.
    """
    _check_points(points)
    axes = principal_frame(covariance(points))
    center, half = box_on_axes(points, axes)
    return center, axes, half


def _as_points(points, faces=None):
    pts = np.ascontiguousarray(np.asarray(points, dtype=np.float64))
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f'bounding volume: points must have shape (n, 3), got {pts.shape}')
    if faces is not None:
        faces = np.asarray(faces)
        if faces.size:
            if faces.min() < 0 or faces.max() >= len(pts):
                raise ValueError(
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
    :raises ValueError: no points, NaN / infinity, or faces out of range.
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
    :raises ValueError: no points, or NaN / infinity in them.
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
    """Fit an oriented box to ``points`` by ``method`` (OBB_PCA, OBB_HULL_PCA, OBB_MIN_VOLUME).

    :param points: (n, 3) float points.
    :param method: one of OBB_PCA (0), OBB_HULL_PCA (1), OBB_MIN_VOLUME (2).
    :param faces: optional (m, 3) int triangles over ``points``; only OBB_HULL_PCA uses them
        (to drop unreferenced vertices).
    :return: (center (3,), axes (3, 3), half (3,)) in the module's convention.
    :raises ValueError: unknown method, no points, or NaN / infinity in them.
    """
    if method == OBB_PCA:
        return fit_obb_pca(_as_points(points))
    if method == OBB_HULL_PCA:
        return fit_obb_hull_pca(points, faces)
    if method == OBB_MIN_VOLUME:
        return fit_obb_min_volume(points)
    raise ValueError(f'fit_obb: unknown method {method!r}; use OBB_PCA (0), OBB_HULL_PCA (1) '
                     'or OBB_MIN_VOLUME (2)')


@numba.njit(cache=True)
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
    :raises ValueError: no points, or NaN / infinity in them.
    """
    _check_points(points)
    n = points.shape[0]
    y = 0
    best = -1.0
    for i in range(n):
        d = ((points[i, 0] - points[0, 0]) ** 2 + (points[i, 1] - points[0, 1]) ** 2
             + (points[i, 2] - points[0, 2]) ** 2)
        if d > best:
            best, y = d, i
    z = y
    best = -1.0
    for i in range(n):
        d = ((points[i, 0] - points[y, 0]) ** 2 + (points[i, 1] - points[y, 1]) ** 2
             + (points[i, 2] - points[y, 2]) ** 2)
        if d > best:
            best, z = d, i
    c = np.empty(3)
    for k in range(3):
        c[k] = 0.5 * (points[y, k] + points[z, k])
    r = 0.5 * math.sqrt(best)
    for i in range(n):
        d0, d1, d2 = points[i, 0] - c[0], points[i, 1] - c[1], points[i, 2] - c[2]
        d = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if d > r:
            # New sphere: the old one and the point on its far side as a diameter.
            r_new = 0.5 * (r + d)
            s = (r_new - r) / d
            c[0] += s * d0
            c[1] += s * d1
            c[2] += s * d2
            r = r_new
    r = 0.0
    for i in range(n):
        d0, d1, d2 = points[i, 0] - c[0], points[i, 1] - c[1], points[i, 2] - c[2]
        r = max(r, math.sqrt(d0 * d0 + d1 * d1 + d2 * d2))
    # The axis-aligned box's circumscribed sphere, when it is smaller.
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for i in range(n):
        for k in range(3):
            lo[k] = min(lo[k], points[i, k])
            hi[k] = max(hi[k], points[i, k])
    cb = 0.5 * (lo + hi)
    rb = 0.0
    for i in range(n):
        d0, d1, d2 = points[i, 0] - cb[0], points[i, 1] - cb[1], points[i, 2] - cb[2]
        rb = max(rb, math.sqrt(d0 * d0 + d1 * d1 + d2 * d2))
    if rb < r:
        return cb, rb
    return c, r


bind_to_kernel_sources(globals())
