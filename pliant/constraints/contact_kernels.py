"""Compiled kernels of the contact pipeline: the detection of points against primitive shapes,
the contacts' tangent frames, the triangle-mesh distance query, and the contact solve (the
projected block Gauss-Seidel sweep, the Alart-Curnier function with its Newton derivative, and
the semismooth Newton iteration judged by the sweeps). The modules collision.py and
friction.py hold the readable definitions and the validation; the tests compare these kernels
with plain references."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# Primitive shapes the detection kernel knows (collision.Shape._kernel), with their sizes.
PLANE, SPHERE, BOX, CAPSULE = range(4)  # (), (radius,), (half extents), (radius, half length)


@njit(cache=True)
def primitive_contacts(points, candidates, lo, hi, kind, size, position, rotation, margin, radius):
    """Contacts of the candidate points, balls of `radius`, inside the box [lo, hi] with one
    primitive shape posed at (position, rotation): the plain definitions of
    collision.Plane/Sphere/Box/Capsule._local_distance and collision._contacts_with_shape,
    point by point and in the same floating-point operations.

    Returns (candidate rows kept, gap, normal, point_a, point_b) for gap = phi - radius <
    margin, in the candidates' order.
    """
    k = candidates.shape[0]
    kept = np.empty(k, dtype=np.int64)
    gap = np.empty(k)
    normal = np.empty((k, 3))
    point_a = np.empty((k, 3))
    point_b = np.empty((k, 3))
    local = np.empty(3)
    n = np.empty(3)
    c = np.empty(3)
    count = 0
    for row in range(k):
        p = points[candidates[row]]
        if not (lo[0] <= p[0] <= hi[0] and lo[1] <= p[1] <= hi[1] and lo[2] <= p[2] <= hi[2]):
            continue
        d0, d1, d2 = p[0] - position[0], p[1] - position[1], p[2] - position[2]
        for a in range(3):  # R^T (p - x)
            local[a] = d0 * rotation[0, a] + d1 * rotation[1, a] + d2 * rotation[2, a]
        if kind == PLANE:
            phi = local[2]
            n[0], n[1], n[2] = 0.0, 0.0, 1.0
            c[0], c[1], c[2] = local[0], local[1], 0.0
        elif kind == SPHERE:
            length = math.sqrt(local[0] * local[0] + local[1] * local[1] + local[2] * local[2])
            n[0], n[1], n[2] = 0.0, 0.0, 1.0  # the centre itself: any direction is a closest one
            if length > 0.0:
                for a in range(3):
                    n[a] = local[a] / length
            phi = length - size[0]
            for a in range(3):
                c[a] = size[0] * n[a]
        elif kind == BOX:
            out0 = max(abs(local[0]) - size[0], 0.0)
            out1 = max(abs(local[1]) - size[1], 0.0)
            out2 = max(abs(local[2]) - size[2], 0.0)
            length = math.sqrt(out0 * out0 + out1 * out1 + out2 * out2)
            for a in range(3):
                c[a] = min(max(local[a], -size[a]), size[a])
            if length > 0.0:
                phi = length
                for a in range(3):
                    n[a] = (local[a] - c[a]) / length
            else:  # inside or on the surface: the nearest face is the one of largest q
                axis = 0
                for a in range(1, 3):
                    if abs(local[a]) - size[a] > abs(local[axis]) - size[axis]:
                        axis = a
                phi = abs(local[axis]) - size[axis]
                side = -1.0 if local[axis] < 0.0 else 1.0
                n[0], n[1], n[2] = 0.0, 0.0, 0.0
                n[axis] = side
                c[axis] = side * size[axis]
        else:  # CAPSULE
            z = min(max(local[2], -size[1]), size[1])
            e0, e1, e2 = local[0], local[1], local[2] - z
            length = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
            n[0], n[1], n[2] = 1.0, 0.0, 0.0  # on the axis: any direction across it
            if length > 0.0:
                n[0], n[1], n[2] = e0 / length, e1 / length, e2 / length
            phi = length - size[0]
            c[0], c[1], c[2] = size[0] * n[0], size[0] * n[1], z + size[0] * n[2]
        g = phi - radius
        if not g < margin:
            continue
        kept[count] = row
        gap[count] = g
        for a in range(3):  # R n, R c + x
            normal[count, a] = n[0] * rotation[a, 0] + n[1] * rotation[a, 1] + n[2] * rotation[a, 2]
            point_b[count, a] = (
                c[0] * rotation[a, 0] + c[1] * rotation[a, 1] + c[2] * rotation[a, 2]
            ) + position[a]
            point_a[count, a] = p[a] - radius * normal[count, a]
        count += 1
    return kept[:count], gap[:count], normal[:count], point_a[:count], point_b[:count]


@njit(cache=True)
def tangent_frames(normals):
    """(k, 3, 3) rows n, t1, t2 of each contact: collision.tangent_frame, compiled."""
    k = normals.shape[0]
    frames = np.empty((k, 3, 3))
    for i in range(k):
        n0, n1, n2 = normals[i, 0], normals[i, 1], normals[i, 2]
        # t1 = n x e, e the world axis least aligned with n (the first of equals).
        a0, a1, a2 = abs(n0), abs(n1), abs(n2)
        if a0 <= a1 and a0 <= a2:
            t0, t1, t2 = 0.0, n2, -n1
        elif a1 <= a2:
            t0, t1, t2 = -n2, 0.0, n0
        else:
            t0, t1, t2 = n1, -n0, 0.0
        norm = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        t0, t1, t2 = t0 / norm, t1 / norm, t2 / norm
        frames[i, 0, 0], frames[i, 0, 1], frames[i, 0, 2] = n0, n1, n2
        frames[i, 1, 0], frames[i, 1, 1], frames[i, 1, 2] = t0, t1, t2
        frames[i, 2, 0] = n1 * t2 - n2 * t1
        frames[i, 2, 1] = n2 * t0 - n0 * t2
        frames[i, 2, 2] = n0 * t1 - n1 * t0
    return frames


@njit(cache=True)
def contact_twist_rows(frames, points, bodies, centres, n):
    """(3k, 6n) rows f . J(p) = (f, a x f) of each contact's frame rows f on the twist of the
    body carrying its point (a = p - x the arm; zero rows for bodies outside [0, n)):
    fem.rigid.contact_twist_jacobian, compiled."""
    k = points.shape[0]
    jac = np.zeros((3 * k, 6 * n))
    for c in range(k):
        i = bodies[c]
        if i < 0 or i >= n:
            continue
        a0, a1, a2 = (
            points[c, 0] - centres[i, 0],
            points[c, 1] - centres[i, 1],
            points[c, 2] - centres[i, 2],
        )
        for r in range(3):
            f0, f1, f2 = frames[c, r, 0], frames[c, r, 1], frames[c, r, 2]
            row = jac[3 * c + r, 6 * i : 6 * i + 6]
            row[0], row[1], row[2] = f0, f1, f2
            row[3], row[4], row[5] = a1 * f2 - a2 * f1, a2 * f0 - a0 * f2, a0 * f1 - a1 * f0
    return jac


# Closest-point features of a triangle (a, b, c): its vertices, its edges ab, bc, ca, its face.
VERTEX_A, VERTEX_B, VERTEX_C, EDGE_AB, EDGE_BC, EDGE_CA, FACE = range(7)

_LEAF_SIZE = 4


def build_bvh(
    triangles: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Bounding-volume hierarchy of axis-aligned boxes over triangles (m, 3, 3).

    Top-down median split of the triangle centroids along their longest spread, leaves of at
    most 4 triangles. Returns (box_min, box_max, child, spans, order): node i bounds the
    triangles order[spans[i, 0]:spans[i, 1]]; its children are child[i] and child[i] + 1, or
    child[i] = -1 at a leaf. Node 0 is the root.
    """
    m = triangles.shape[0]
    lo_tri, hi_tri = triangles.min(axis=1), triangles.max(axis=1)
    centroid = triangles.mean(axis=1)
    order = np.arange(m, dtype=np.int64)
    child, spans = [-1], [(0, m)]
    pending = [0]
    while pending:
        node = pending.pop()
        start, stop = spans[node]
        if stop - start <= _LEAF_SIZE:
            continue
        ids = order[start:stop]
        c = centroid[ids]
        half = (stop - start) // 2
        order[start:stop] = ids[np.argpartition(c[:, int(np.argmax(np.ptp(c, axis=0)))], half)]
        child[node] = len(child)
        for span in ((start, start + half), (start + half, stop)):
            pending.append(len(child))
            child.append(-1)
            spans.append(span)
    spans_array = np.array(spans, dtype=np.int64)
    box_min = np.array([lo_tri[order[a:b]].min(axis=0) for a, b in spans])
    box_max = np.array([hi_tri[order[a:b]].max(axis=0) for a, b in spans])
    return box_min, box_max, np.array(child, dtype=np.int64), spans_array, order


@njit(cache=True)
def _dot(x0, x1, x2, y0, y1, y2):
    return x0 * y0 + x1 * y1 + x2 * y2


@njit(cache=True)
def _closest_on_triangle(p, tri):
    """Closest point of the triangle tri = (a, b, c) to p and its feature (Ericson, Real-Time
    Collision Detection, 5.1.5: Voronoi regions of the vertices, the edges, then the face).
    Scalar arithmetic: no temporary arrays in the innermost loop."""
    ax, ay, az = tri[0, 0], tri[0, 1], tri[0, 2]
    abx, aby, abz = tri[1, 0] - ax, tri[1, 1] - ay, tri[1, 2] - az
    acx, acy, acz = tri[2, 0] - ax, tri[2, 1] - ay, tri[2, 2] - az
    apx, apy, apz = p[0] - ax, p[1] - ay, p[2] - az
    d1, d2 = _dot(abx, aby, abz, apx, apy, apz), _dot(acx, acy, acz, apx, apy, apz)
    if d1 <= 0.0 and d2 <= 0.0:
        return 0.0, 0.0, VERTEX_A
    bpx, bpy, bpz = apx - abx, apy - aby, apz - abz
    d3, d4 = _dot(abx, aby, abz, bpx, bpy, bpz), _dot(acx, acy, acz, bpx, bpy, bpz)
    if d3 >= 0.0 and d4 <= d3:
        return 1.0, 0.0, VERTEX_B
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        return d1 / (d1 - d3), 0.0, EDGE_AB
    cpx, cpy, cpz = apx - acx, apy - acy, apz - acz
    d5, d6 = _dot(abx, aby, abz, cpx, cpy, cpz), _dot(acx, acy, acz, cpx, cpy, cpz)
    if d6 >= 0.0 and d5 <= d6:
        return 0.0, 1.0, VERTEX_C
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        return 0.0, d2 / (d2 - d6), EDGE_CA
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return 1.0 - w, w, EDGE_BC
    denom = 1.0 / (va + vb + vc)
    return vb * denom, vc * denom, FACE


@njit(cache=True)
def _box_distance2(p, lo, hi):
    d2 = 0.0
    for k in range(3):
        if p[k] < lo[k]:
            d2 += (lo[k] - p[k]) ** 2
        elif p[k] > hi[k]:
            d2 += (p[k] - hi[k]) ** 2
    return d2


@njit(cache=True)
def closest_points(points, triangles, box_min, box_max, child, spans, order):
    """For each point: squared distance to the mesh, closest point, triangle and feature.

    Depth-first traversal nearest child first, pruning boxes farther than the best distance.
    """
    n = points.shape[0]
    dist2 = np.empty(n)
    closest = np.empty((n, 3))
    triangle = np.empty(n, dtype=np.int64)
    feature = np.empty(n, dtype=np.int64)
    stack = np.empty(128, dtype=np.int64)
    best_point = np.zeros(3)
    for i in range(n):
        p = points[i]
        best, best_tri, best_feature = np.inf, -1, FACE
        stack[0] = 0  # the root
        top = 1
        while top > 0:
            top -= 1
            node = stack[top]
            if _box_distance2(p, box_min[node], box_max[node]) >= best:
                continue
            first = child[node]
            if first < 0:
                for s in range(spans[node, 0], spans[node, 1]):
                    t = order[s]
                    tri = triangles[t]
                    # The closest point is a + v (b - a) + w (c - a).
                    v, w, f = _closest_on_triangle(p, tri)
                    qx = tri[0, 0] + v * (tri[1, 0] - tri[0, 0]) + w * (tri[2, 0] - tri[0, 0])
                    qy = tri[0, 1] + v * (tri[1, 1] - tri[0, 1]) + w * (tri[2, 1] - tri[0, 1])
                    qz = tri[0, 2] + v * (tri[1, 2] - tri[0, 2]) + w * (tri[2, 2] - tri[0, 2])
                    d2 = (p[0] - qx) ** 2 + (p[1] - qy) ** 2 + (p[2] - qz) ** 2
                    if d2 < best:
                        best, best_tri, best_feature = d2, t, f
                        best_point[0], best_point[1], best_point[2] = qx, qy, qz
                continue
            near = _box_distance2(p, box_min[first], box_max[first])
            far = _box_distance2(p, box_min[first + 1], box_max[first + 1])
            if near <= far:
                stack[top], stack[top + 1] = first + 1, first
            else:
                stack[top], stack[top + 1] = first, first + 1
            top += 2
        dist2[i], closest[i], triangle[i], feature[i] = best, best_point, best_tri, best_feature
    return dist2, closest, triangle, feature


@njit(cache=True)
def matrix_summary(w):
    """(all entries finite, max |w_ij|, max |w_ij - w_ji|) of a square matrix, in one pass."""
    scale = asymmetry = 0.0
    for i in range(w.shape[0]):
        for j in range(i, w.shape[0]):
            a, b = w[i, j], w[j, i]
            if not (math.isfinite(a) and math.isfinite(b)):
                return False, math.nan, math.nan
            scale = max(scale, abs(a), abs(b))
            asymmetry = max(asymmetry, abs(a - b))
    return True, scale, asymmetry


@njit(cache=True)
def _disk_qp(a, b, c, g1, g2, radius):
    """argmin 1/2 x^T T x + g^T x subject to |x| <= radius, T = [[a, b], [b, c]] PSD.

    Interior: T x = -g. Boundary: (T + nu I) x = -g with |x| = radius, nu >= 0 (the 2D trust-
    region subproblem), found in T's eigenbasis by safeguarded Newton on the secular equation
    1/|x(nu)| - 1/radius = 0, which is nearly linear in nu (More and Sorensen, 1983).
    """
    if radius <= 0.0:
        return 0.0, 0.0
    # Eigen-decomposition of the symmetric 2x2 T: e1 <= e2, unit eigenvectors u (e1), v (e2).
    mean, diff = 0.5 * (a + c), 0.5 * (a - c)
    root = math.sqrt(diff * diff + b * b)
    e1, e2 = mean - root, mean + root
    v1, v2 = 1.0, 0.0
    if root > 0.0:
        # Two expressions of e2's eigenvector; take the better conditioned one.
        p1, p2, q1, q2 = b, e2 - a, e2 - c, b
        if math.hypot(p1, p2) < math.hypot(q1, q2):
            p1, p2 = q1, q2
        norm = math.hypot(p1, p2)
        v1, v2 = p1 / norm, p2 / norm
    u1, u2 = -v2, v1
    h1, h2 = u1 * g1 + u2 * g2, v1 * g1 + v2 * g2  # g in the eigenbasis
    scale = max(abs(e2), 1e-300)
    tiny = 1e-14 * scale
    # Minimum-norm stationary point at nu = 0 (directions of zero curvature with zero slope
    # leave the objective flat: the shortest minimiser is inside whenever any one is).
    x1 = 0.0 if abs(e1) <= tiny and h1 == 0.0 else (-h1 / e1 if e1 > tiny else math.inf)
    x2 = 0.0 if abs(e2) <= tiny and h2 == 0.0 else (-h2 / e2 if e2 > tiny else math.inf)
    if x1 * x1 + x2 * x2 <= radius * radius:
        return u1 * x1 + v1 * x2, u2 * x1 + v2 * x2
    lo, hi = 0.0, math.hypot(h1, h2) / radius  # |x(hi)| <= |g| / hi = radius
    nu = lo if e1 > tiny else hi
    y1 = y2 = 0.0
    for _ in range(100):
        y1, y2 = -h1 / (max(e1, 0.0) + nu), -h2 / (max(e2, 0.0) + nu)
        norm = math.hypot(y1, y2)
        residual = 1.0 / norm - 1.0 / radius
        if abs(residual) * radius <= 1e-15:
            break
        if residual < 0.0:
            lo = nu
        else:
            hi = nu
        slope = (y1 * y1 / (max(e1, 0.0) + nu) + y2 * y2 / (max(e2, 0.0) + nu)) / (
            norm * norm * norm
        )
        step = nu - residual / slope
        nu = step if lo < step < hi else 0.5 * (lo + hi)
    scale_to_disk = radius / math.hypot(y1, y2)
    y1, y2 = y1 * scale_to_disk, y2 * scale_to_disk
    return u1 * y1 + v1 * y2, u2 * y1 + v2 * y2


@njit(cache=True)
def _add_column(delta, w, row, change):
    """delta += W[:, row] * change, reading the symmetric W by (contiguous) rows."""
    if change != 0.0:
        for j in range(delta.shape[0]):
            delta[j] += w[row, j] * change


@njit(cache=True)
def _actuator_law(rest, wii, displacement_mode, command, force_lo, force_hi, course_lo, course_hi):
    """An actuator row's force given rest = delta_i - W_ii lambda_i (its displacement without
    its own force), and the displacement that force holds, or NaN where the force is a bound or
    the command: the law of :func:`pliant.constraints.direct.solve_direct`, one row at a time.

    Displacement mode: the command clamped to the course, held by a force within its bounds.
    Force mode: the commanded force, unless it drives delta out of its course: then the force
    that holds delta on that bound, no further from the command.
    """
    if displacement_mode:
        target = min(max(command, course_lo), course_hi)
        held = (target - rest) / wii
        if held < force_lo:
            return force_lo, math.nan
        if held > force_hi:
            return force_hi, math.nan
        return held, target
    force = min(max(command, force_lo), force_hi)
    reached = wii * force + rest
    if reached > course_hi:  # the upper course bound lowers the force, down to force_lo
        held = (course_hi - rest) / wii
        if held < force_lo:
            return force_lo, math.nan
        if held > force:
            return force, math.nan
        return held, course_hi
    if reached < course_lo:
        held = (course_lo - rest) / wii
        if held > force_hi:
            return force_hi, math.nan
        if held < force:
            return force, math.nan
        return held, course_lo
    return force, math.nan


@njit(cache=True)
def _negligible(w):
    """The diagonal entry below which a row is one that no force moves (e.g. a contact on a
    fixed node): 1e-14 of the largest."""
    tiny = 0.0
    for i in range(w.shape[0]):
        tiny = max(tiny, 1e-14 * abs(w[i, i]))
    return tiny


@njit(cache=True)
def gauss_seidel(
    w,
    delta_free,
    lam,
    actuator_rows,
    displacement_mode,
    command,
    force_lo,
    force_hi,
    course_lo,
    course_hi,
    contact_start,
    friction,
    tolerance,
    max_iterations,
):
    """Projected block Gauss-Seidel on delta = W lambda + delta_free; `lam` is updated in place.

    One sweep visits each actuator row, then each contact block (normal, t1, t2), and replaces
    its lambda by the exact solution of its own law with the other lambdas fixed. Returns the
    number of sweeps and the residual of the last one: the largest displacement correction
    |W_bb (lambda_b_new - lambda_b_old)|_inf that a block received.
    """
    delta = w @ lam + delta_free
    n_contacts = friction.shape[0]
    tiny = _negligible(w)
    residual = np.inf
    for sweep in range(max_iterations):
        residual = 0.0
        for j in range(actuator_rows.shape[0]):
            i = actuator_rows[j]
            wii = w[i, i]
            if wii <= tiny:
                continue
            new, _ = _actuator_law(
                delta[i] - wii * lam[i],
                wii,
                displacement_mode[j],
                command[j],
                force_lo[j],
                force_hi[j],
                course_lo[j],
                course_hi[j],
            )
            change = new - lam[i]
            lam[i] = new
            _add_column(delta, w, i, change)
            residual = max(residual, abs(wii * change))
        for k in range(n_contacts):
            n = contact_start + 3 * k
            t1, t2 = n + 1, n + 2
            wnn = w[n, n]
            if wnn <= tiny:
                continue  # a row that no force can move (e.g. a contact on a fixed node)
            before_n, before_1, before_2 = delta[n], delta[t1], delta[t2]
            # Signorini: 0 <= delta_n  _|_  lambda_n >= 0.
            new_n = max(0.0, lam[n] - delta[n] / wnn)
            _add_column(delta, w, n, new_n - lam[n])
            lam[n] = new_n
            # Coulomb: lambda_t minimises the block's energy in the disk |lambda_t| <= mu lambda_n,
            # so delta_t = 0 inside (stick) or delta_t = -nu lambda_t on the rim (slip).
            a, b, c = w[t1, t1], w[t1, t2], w[t2, t2]
            g1 = delta[t1] - a * lam[t1] - b * lam[t2]
            g2 = delta[t2] - b * lam[t1] - c * lam[t2]
            new_1, new_2 = _disk_qp(a, b, c, g1, g2, friction[k] * new_n)
            _add_column(delta, w, t1, new_1 - lam[t1])
            _add_column(delta, w, t2, new_2 - lam[t2])
            lam[t1], lam[t2] = new_1, new_2
            residual = max(
                residual,
                abs(delta[n] - before_n),
                abs(delta[t1] - before_1),
                abs(delta[t2] - before_2),
            )
        if residual <= tolerance:
            return sweep + 1, residual
    return max_iterations, residual


@njit(cache=True)
def _add_row(jacobian, proximal, row, w, source, scale):
    """Row `row` of the derivative gains scale * W[source], and of the proximal term
    scale * W[source, source] on column `source`."""
    for j in range(w.shape[0]):
        jacobian[row, j] += scale * w[source, j]
    proximal[row, source] += scale * w[source, source]


@njit(cache=True)
def alart_curnier(
    w,
    delta,
    lam,
    actuator_rows,
    displacement_mode,
    command,
    force_lo,
    force_hi,
    course_lo,
    course_hi,
    contact_start,
    friction,
    jacobian,
    proximal,
):
    """F(lambda), zero exactly at the solutions of the contact problem, and the rows of lambda
    that a Newton step moves freely. When `jacobian` and `proximal` are (r, r), they receive an
    element J of F's Newton derivative and P, the term that replacing W by W + eps diag(W) in
    the derivatives of delta adds to it per unit eps (rho and the rows' scales kept).

    Contact k, rho = 1 / W_nn, sigma = lambda - rho delta (Alart and Curnier, CMAME 92, 1991):

        sigma_n <= 0 (open):      F = lambda
        else, normal:             F_n = rho delta_n
              |sigma_t| <= R:     F_t = rho delta_t                       (stick)
              |sigma_t| >  R:     F_t = lambda_t - R sigma_t / |sigma_t|  (slip)

    with R = mu sigma_n. For any rho > 0, F = 0 is Signorini's law and Coulomb's with the exact
    disk. Actuator row i: F_i = (delta_i - target) / W_ii where its law holds a displacement,
    else lambda_i - force (:func:`_actuator_law`). Other rows (effectors, rows that no force
    moves) keep lambda: F_i = 0 and a unit row, as Gauss-Seidel leaves them.
    """
    r = lam.shape[0]
    f = np.zeros(r)
    free = np.zeros(r, dtype=np.bool_)
    with_jacobian = jacobian.shape[0] == r
    if with_jacobian:
        jacobian[:, :] = 0.0
        proximal[:, :] = 0.0
        for i in range(r):
            jacobian[i, i] = 1.0
    tiny = _negligible(w)
    for j in range(actuator_rows.shape[0]):
        i = actuator_rows[j]
        wii = w[i, i]
        if wii <= tiny:
            continue
        force, target = _actuator_law(
            delta[i] - wii * lam[i],
            wii,
            displacement_mode[j],
            command[j],
            force_lo[j],
            force_hi[j],
            course_lo[j],
            course_hi[j],
        )
        if math.isnan(target):
            f[i] = lam[i] - force
            continue
        f[i] = (delta[i] - target) / wii
        free[i] = True
        if with_jacobian:
            jacobian[i, i] = 0.0
            _add_row(jacobian, proximal, i, w, i, 1.0 / wii)
    for k in range(friction.shape[0]):
        n = contact_start + 3 * k
        t1, t2 = n + 1, n + 2
        if w[n, n] <= tiny:
            continue
        rho = 1.0 / w[n, n]
        sigma_n = lam[n] - rho * delta[n]
        if sigma_n <= 0.0:
            f[n], f[t1], f[t2] = lam[n], lam[t1], lam[t2]
            continue
        free[n] = free[t1] = free[t2] = True
        f[n] = rho * delta[n]
        s1, s2 = lam[t1] - rho * delta[t1], lam[t2] - rho * delta[t2]
        radius = friction[k] * sigma_n
        norm = math.hypot(s1, s2)
        if with_jacobian:
            jacobian[n, n] = 0.0
            _add_row(jacobian, proximal, n, w, n, rho)
        if norm <= radius:
            f[t1], f[t2] = rho * delta[t1], rho * delta[t2]
            if with_jacobian:
                jacobian[t1, t1] = jacobian[t2, t2] = 0.0
                _add_row(jacobian, proximal, t1, w, t1, rho)
                _add_row(jacobian, proximal, t2, w, t2, rho)
            continue
        u1, u2 = s1 / norm, s2 / norm
        f[t1], f[t2] = lam[t1] - radius * u1, lam[t2] - radius * u2
        if not with_jacobian:
            continue
        # d(R u) = u dR + (R / |sigma_t|) (I - u u^T) d sigma_t, dR = mu d sigma_n,
        # d sigma = d lambda - rho W d lambda.
        c, mu = radius / norm, friction[k]
        u = (u1, u2)
        for a in range(2):
            row = n + 1 + a
            jacobian[row, n] -= mu * u[a]
            _add_row(jacobian, proximal, row, w, n, mu * u[a] * rho)
            for b in range(2):
                projector = (1.0 if a == b else 0.0) - u[a] * u[b]  # (I - u u^T)_ab
                jacobian[row, n + 1 + b] -= c * projector
                _add_row(jacobian, proximal, row, w, n + 1 + b, c * projector * rho)
    return f, free


# The proximal weight eps of Newton's matrix J + eps P (P: the term of W + eps diag(W)) is
# adapted as a Levenberg-Marquardt parameter (More, Lecture Notes in Math. 630, 1978): divided
# by 10 after a full step, multiplied by 100 (at most twice a step) when the line search fails.
# The smallest keeps Newton exact to round-off on a well-posed problem (with one refinement,
# the error is eps^2); the largest damps the steps on an indeterminate one.
PROXIMAL_MIN, PROXIMAL_MAX = 1e-8, 1e-2
# Armijo's line search: sufficient decrease 1e-4 of |F|^2 per unit step, steps down to 2^-13.
ARMIJO, SHORTEST_STEP = 1e-4, 1e-4
#: Newton steps only on problems of at most this many rows: a step factorises a dense r x r
#: matrix (O(r^3) time, two r x r arrays), where a Gauss-Seidel sweep costs O(r^2). Above it
#: the sweeps run alone: CatchTheObject at dt 0.1 screens 2 027 candidate contacts (6 082
#: rows), of which one or two end active; 159 sweeps solve it in 0.14 s, the Newton steps took
#: 240 s and 600 MB.
NEWTON_MAX_ROWS = 1500


@njit(cache=True)
def _newton_direction(f, free, jacobian, proximal, eps):
    """x with (J + eps P) x = -F, refined once towards J x = -F; None if singular.

    Rows outside `free` have unit rows in J (and none in P): they move by -F. The others solve
    the reduced system. Where J is invertible the refined x is J^-1 (-F) to O(eps^2); where it
    is singular (W of a rigid box on its corners, an indeterminate grasp), P selects the
    smallest move of lambda, the step of a proximal point iteration.
    """
    direction = -f
    index = np.flatnonzero(free)
    m = index.size
    if m == 0:
        return direction
    exact = np.empty((m, m))
    regularised = np.empty((m, m))
    rhs = np.empty(m)
    for a in range(m):
        i = index[a]
        value = -f[i]
        for j in range(f.shape[0]):
            if not free[j]:
                value -= jacobian[i, j] * direction[j]
        rhs[a] = value
        for b in range(m):
            exact[a, b] = jacobian[i, index[b]]
            regularised[a, b] = exact[a, b] + eps * proximal[i, index[b]]
    try:
        x = np.linalg.solve(regularised, rhs)
        x += np.linalg.solve(regularised, rhs - exact @ x)
    except Exception:  # noqa: BLE001 (numba raises a plain Exception on a singular matrix)
        return None
    if not np.all(np.isfinite(x)):
        return None
    direction[index] = x
    return direction


@njit(cache=True)
def _newton_step(w, delta_free, lam, blocks, eps, jacobian, proximal):
    """One damped Newton step on F (:func:`alart_curnier`) from lam, in place: the longest of
    1, 1/2, 1/4, ... that decreases |F|^2 by Armijo's rule, retried with a larger proximal
    weight when none does. Returns (whether lam moved, the proximal weight for the next step).
    """
    delta = w @ lam + delta_free
    f, free = alart_curnier(w, delta, lam, *blocks, jacobian, proximal)
    merit = f @ f
    no_jacobian = np.empty((0, 0))
    for _ in range(3):
        direction = _newton_direction(f, free, jacobian, proximal, eps)
        if direction is not None:
            change = w @ direction
            step = 1.0
            while step >= SHORTEST_STEP:
                trial = lam + step * direction
                f_trial, _ = alart_curnier(
                    w, delta + step * change, trial, *blocks, no_jacobian, no_jacobian
                )
                if f_trial @ f_trial <= (1.0 - ARMIJO * step) * merit:
                    lam[:] = trial
                    return True, max(PROXIMAL_MIN, eps / 10.0) if step == 1.0 else eps
                step *= 0.5
        if eps >= PROXIMAL_MAX:
            break
        eps = min(PROXIMAL_MAX, 100.0 * eps)
    return False, eps


@njit(cache=True)
def newton_gauss_seidel(w, delta_free, lam, blocks, tolerance, max_iterations):
    """The contact problem by semismooth Newton on F (:func:`alart_curnier`), judged by
    Gauss-Seidel; `lam` (the warm start) is updated in place.

    Each iteration makes one Gauss-Seidel sweep from lam, whose residual is the convergence
    test, then a Newton step from lam, or takes the sweep's result where the step fails (or
    where the problem has more than ``NEWTON_MAX_ROWS`` rows: plain Gauss-Seidel there).
    Returns (sweeps, Newton steps, residual of the last sweep); lam is that sweep's result.
    """
    r = lam.shape[0]
    newton = r <= NEWTON_MAX_ROWS
    size = r if newton else 0
    jacobian = np.empty((size, size))
    proximal = np.empty((size, size))
    swept = np.empty(r)
    eps = PROXIMAL_MIN
    newton_steps = 0
    sweeps, residual = 0, np.inf
    while sweeps < max_iterations:
        swept[:] = lam
        _, residual = gauss_seidel(w, delta_free, swept, *blocks, tolerance, 1)
        sweeps += 1
        if residual <= tolerance or sweeps == max_iterations:
            break
        moved = False
        if newton:
            moved, eps = _newton_step(w, delta_free, lam, blocks, eps, jacobian, proximal)
        if moved:
            newton_steps += 1
        else:
            lam[:] = swept
    lam[:] = swept
    return sweeps, newton_steps, residual
