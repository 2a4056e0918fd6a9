"""xslit_fit benchmark: a two-slit fit of 1 M rays and a 16×16 tile map of a 2 MP cylinder ray map.

Targets (issue 4): the 1 M-ray fit under 1 s, the tile map under 5 s. Rays come from small
closed-form generators here (exact XSlit; analytic cylinder reflection), not from raytrace,
so only the fitting is timed.
"""

from __future__ import annotations

import time

import numpy as np

from xslit_fit import fit_tiles, fit_two_slits


def xslit_rays(n: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """n rays through two random skew slits; points moved along the rays."""
    q1, q2 = rng.normal(size=3), 2 * rng.normal(size=3)
    u1, u2 = rng.normal(size=3), rng.normal(size=3)
    a = q1 + rng.uniform(-1, 1, (n, 1)) * u1
    b = q2 + rng.uniform(-1, 1, (n, 1)) * u2
    d = (b - a) / np.linalg.norm(b - a, axis=1, keepdims=True)
    return a + rng.uniform(-2, 2, (n, 1)) * d, d


def cylinder_ray_map(radius=0.1, distance=0.6, width=1632, height=1224, focal=3500.0):
    """Reflected rays of a cylinder (axis world y) seen from (0, 0, distance) looking at it."""
    u, v = np.meshgrid(np.arange(width, dtype=float), np.arange(height, dtype=float))
    cam = np.stack([(u - (width - 1) / 2) / focal, (v - (height - 1) / 2) / focal,
                    np.ones_like(u)], -1)
    d = cam @ np.diag([1.0, -1.0, -1.0])
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    a = d[..., 0] ** 2 + d[..., 2] ** 2
    b = distance * d[..., 2]
    disc = b * b - a * (distance**2 - radius**2)
    valid = disc > 0
    t = (-b - np.sqrt(np.where(valid, disc, 0.0))) / np.where(a > 0, a, 1.0)
    hit = np.array([0.0, 0.0, distance]) + t[..., None] * d
    n = hit * np.array([1.0, 0.0, 1.0]) / radius
    refl = d - 2 * np.sum(d * n, -1, keepdims=True) * n
    return hit, refl, valid


def best_of(fn, repeat: int = 3) -> tuple[float, object]:
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    rng = np.random.default_rng(0)
    p, d = xslit_rays(1_000_000, rng)
    t_fit, fit = best_of(lambda: fit_two_slits(p, d))
    t_lin, _ = best_of(lambda: fit_two_slits(p, d, refine=False))
    print(f"fit_two_slits, 1 M exact XSlit rays: {t_fit:.3f} s (target < 1 s; "
          f"linear step only {t_lin:.3f} s), rms {fit.rms_distance:.2e}")

    hit, refl, valid = cylinder_ray_map()
    mp = valid.size / 1e6
    t_map, tm = best_of(lambda: fit_tiles(hit, refl, valid, tiles=(16, 16)), repeat=2)
    print(f"fit_tiles 16x16, {mp:.1f} MP cylinder ray map ({valid.mean():.0%} mirror): "
          f"{t_map:.3f} s (target < 5 s), {int(tm.valid.sum())} valid tiles, "
          f"{t_map / 256 * 1e3:.1f} ms per tile")
    print(f"ratios to target: fit {t_fit / 1.0:.2f}, tile map {t_map / 5.0:.2f}")


if __name__ == "__main__":
    main()
