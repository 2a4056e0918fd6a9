"""Independent ray generators for the xslit_fit tests: exact XSlits, GLC bundles, a cylinder mirror.

These use only numpy and closed-form geometry (ray-cylinder intersection, the reflection
law, lines through two points), never the code under test.
"""

import numpy as np


def random_rotation(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    return q


def unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def xslit_rays(slit1, slit2, n, rng, span=1.0, along=2.0):
    """n rays through random points of two slits (point, unit direction) each.

    Ray points are moved a random distance along each ray so they are not on the slits."""
    (q1, u1), (q2, u2) = slit1, slit2
    a = q1 + rng.uniform(-span, span, (n, 1)) * u1
    b = q2 + rng.uniform(-span, span, (n, 1)) * u2
    d = unit(b - a)
    return a + rng.uniform(-along, along, (n, 1)) * d, d


def ray_through_point_and_slits(points, slit1, slit2):
    """For scene points (N, 3), the direction of the line through each point meeting both
    slits: the intersection of the planes (point, slit 1) and (point, slit 2)."""
    (q1, u1), (q2, u2) = slit1, slit2
    n1 = np.cross(points - q1, u1)
    n2 = np.cross(points - q2, u2)
    return unit(np.cross(n1, n2))


GLC_KINDS = {
    "xslit": np.diag([0.7, -0.3]),
    "pinhole": np.diag([0.5, 0.5]),
    "pencil": np.array([[0.5, 0.4], [0.0, 0.5]]),
    "pushbroom": np.diag([0.6, 0.0]),
    "orthographic": np.zeros((2, 2)),
    "twisted_orthographic": np.array([[0.0, 0.5], [0.0, 0.0]]),
    "bilinear": np.array([[0.3, -0.5], [0.5, 0.3]]),
}


def glc_bundle(kind, rng, n=15, c=(0.0, 0.0)):
    """A GLC bundle in a two-plane parameterisation, then moved by a random rigid motion.

    Rays meet z = 0 at (u, v) and z = 1 at (s, t) = (u, v) + K'·(u, v) + c with
    K' = B·K·B⁻¹, K from GLC_KINDS: the characteristic polynomial is det(I + λ·K'), so the
    eigen-structure of K fixes the type (distinct real: xslit, scalar: pinhole, Jordan:
    pencil, one zero: pushbroom, zero: orthographic, nilpotent: twisted, complex: bilinear).
    """
    basis = rng.normal(size=(2, 2)) * 0.3 + np.eye(2)
    k = basis @ GLC_KINDS[kind] @ np.linalg.inv(basis)
    g = np.linspace(-1, 1, n)
    u, v = np.meshgrid(g, g)
    uv = np.stack([u.ravel(), v.ravel()], 1)
    st = uv + uv @ k.T + np.asarray(c)
    pts = np.concatenate([uv, np.zeros((len(uv), 1))], 1)
    dirs = unit(np.concatenate([st - uv, np.ones((len(uv), 1))], 1))
    pts = pts + rng.uniform(-0.5, 0.5, (len(pts), 1)) * dirs
    rot = random_rotation(rng)
    shift = rng.normal(size=3)
    return pts @ rot.T + shift, dirs @ rot.T


def cylinder_rays(radius, distance, width=640, height=480, focal=1500.0, roi=None):
    """Reflected rays of a cylinder mirror seen by an OpenCV pinhole camera.

    Mirror: axis = world y through the origin. Camera at (0, 0, distance) looking at the
    origin with up = +y (so camera x = world x, camera y = −world y, camera z = −world z).
    Returns mirror points (h, w, 3), reflected directions (h, w, 3), valid (h, w).
    roi = (x0, y0, x1, y1) pixel bounds (x1, y1 exclusive) restricts the pixels.
    """
    cx, cy = (width - 1) / 2, (height - 1) / 2
    x0, y0, x1, y1 = (0, 0, width, height) if roi is None else roi
    u, v = np.meshgrid(np.arange(x0, x1, dtype=float), np.arange(y0, y1, dtype=float))
    return cylinder_rays_at(radius, distance, u, v, focal, cx, cy)


def cylinder_rays_at(radius, distance, u, v, focal, cx, cy):
    """Reflected rays of the cylinder of `cylinder_rays` at (sub-)pixels u, v (any shape)."""
    cam = np.stack([(u - cx) / focal, (v - cy) / focal, np.ones_like(u)], -1)
    d = unit(cam @ np.diag([1.0, -1.0, -1.0]))
    o = np.array([0.0, 0.0, distance])
    a = d[..., 0] ** 2 + d[..., 2] ** 2
    b = o[0] * d[..., 0] + o[2] * d[..., 2]
    c = o[0] ** 2 + o[2] ** 2 - radius**2
    disc = b * b - a * c
    valid = disc > 0
    t = (-b - np.sqrt(np.where(valid, disc, 0.0))) / np.where(a > 0, a, 1.0)
    hit = o + t[..., None] * d
    normal = hit * np.array([1.0, 0.0, 1.0]) / radius
    refl = d - 2 * np.sum(d * normal, -1, keepdims=True) * normal
    return hit, refl, valid
