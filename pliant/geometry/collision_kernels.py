"""Compiled kernels of collision detection: points against primitive shapes, the contacts'
tangent frames, and the triangle-mesh distance query over a bounding-volume hierarchy. The
module collision.py holds the readable definitions and the validation; the tests compare these
kernels with plain references."""

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
def closest_on_triangles(points, triangles, point_index, triangle_index):
    """For each pair (point point_index[i], triangle triangle_index[i]): the closest point of
    the triangle (a, b, c) as a + v (b - a) + w (c - a), (k, 2) (v, w), and its feature."""
    k = point_index.shape[0]
    vw = np.empty((k, 2))
    feature = np.empty(k, dtype=np.int64)
    for i in range(k):
        v, w, f = _closest_on_triangle(points[point_index[i]], triangles[triangle_index[i]])
        vw[i, 0], vw[i, 1], feature[i] = v, w, f
    return vw, feature


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
