"""Tests of depth.dense: MRF solvers on toy graphs with known optima, superpixel graph, geodesic blending."""

import itertools

import numpy as np
import pytest

from depth.dense import (dense_depth, initial_depths, mrf_energy, solve_graphcut, solve_quadratic,
                         superpixel_graph)


def random_graph(rng, n, p=0.4):
    e = np.array([(i, j) for i in range(n) for j in range(i + 1, n) if rng.random() < p])
    return e, rng.uniform(0.2, 1.0, len(e))


def brute_force(v, conf, e, w, lam, labels):
    best = np.inf
    for combo in itertools.product(labels, repeat=len(v)):
        best = min(best, mrf_energy(np.array(combo), v, conf, e, w, lam))
    return best


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_graphcut_two_labels_is_exact(seed):
    rng = np.random.default_rng(seed)
    n = 10
    e, w = random_graph(rng, n)
    v = rng.uniform(0, 1, n)
    conf = rng.uniform(0.1, 1, n)
    labels = np.array([0.2, 0.8])
    u = solve_graphcut(v, conf, e, w, 0.7, labels)
    assert mrf_energy(u, v, conf, e, w, 0.7) == pytest.approx(brute_force(v, conf, e, w, 0.7, labels), rel=1e-9)


def test_graphcut_multilabel_within_expansion_bound():
    rng = np.random.default_rng(5)
    n = 7
    e, w = random_graph(rng, n, 0.5)
    v = rng.uniform(0, 3, n)
    conf = np.ones(n)
    labels = np.array([0.0, 1.0, 2.0, 3.0])
    opt = brute_force(v, conf, e, w, 0.8, labels)
    got = mrf_energy(solve_graphcut(v, conf, e, w, 0.8, labels), v, conf, e, w, 0.8)
    assert opt - 1e-12 <= got <= 2 * opt + 1e-12


def test_graphcut_chain_known_optimum():
    """A chain, left half observed at 1, right half at 3: with weak smoothness the cut is at the middle;
    with λ·w above the data cost of the whole side everything takes one label."""
    n = 8
    e = np.column_stack([np.arange(n - 1), np.arange(1, n)])
    w = np.ones(n - 1)
    v = np.r_[np.full(4, 1.0), np.full(4, 3.0)]
    u = solve_graphcut(v, np.ones(n), e, w, 0.5, np.array([1.0, 2.0, 3.0]))
    np.testing.assert_array_equal(u, v)
    conf = np.r_[np.full(4, 1.0), np.full(4, 0.01)]
    u = solve_graphcut(v, conf, e, w, 5.0, np.array([1.0, 2.0, 3.0]))
    np.testing.assert_array_equal(u, np.ones(n))


def test_quadratic_two_nodes_closed_form_and_dense_solve():
    lam = 0.6
    u = solve_quadratic([0.0, 1.0], [1.0, 1.0], [[0, 1]], [1.0], lam)
    np.testing.assert_allclose(u, [lam / (1 + 2 * lam), (1 + lam) / (1 + 2 * lam)], rtol=1e-10)
    rng = np.random.default_rng(9)
    n = 12
    e, w = random_graph(rng, n)
    v, conf = rng.uniform(1, 5, n), rng.uniform(0.1, 1, n)
    lap = np.zeros((n, n))
    for (i, j), wij in zip(e, w):
        lap[i, i] += wij
        lap[j, j] += wij
        lap[i, j] -= wij
        lap[j, i] -= wij
    want = np.linalg.solve(np.diag(conf) + 0.3 * lap, conf * v)
    np.testing.assert_allclose(solve_quadratic(v, conf, e, w, 0.3), want, rtol=1e-8)


def test_superpixels_and_blending_on_two_regions():
    img = np.zeros((40, 60))
    img[:, 30:] = 1.0
    labels = (np.arange(60)[None, :] >= 30).astype(int) * 1 + np.zeros((40, 1), int)
    labels = labels * 2 + (np.arange(40)[:, None] >= 20)  # four blocks
    g = superpixel_graph(img, labels=labels)
    assert g.n == 4 and len(g.edges) == 4
    # the bright-dark boundary gets a small weight, same-colour neighbours weight ~1
    dark_pair = np.flatnonzero((g.color[g.edges[:, 0], 0] == 0) & (g.color[g.edges[:, 1], 0] == 0))
    cross = np.flatnonzero(g.color[g.edges[:, 0], 0] != g.color[g.edges[:, 1], 0])
    assert np.all(g.weight[cross] < 1e-3) and g.weight[dark_pair][0] > 0.5
    v, conf = initial_depths(g, [[5, 5], [50, 35]], [10.0, 20.0])
    # own cue at geodesic distance 0 (weight 1); the other across the colour edge, weight exp(−g/σ_g) ≪ 1
    a, b = g.labels[5, 5], g.labels[35, 50]
    assert 10.0 < v[a] < 10.05 and 19.95 < v[b] < 20.0
    assert conf[a] == conf[b] == 1.0 and v[a] - 10.0 == pytest.approx(20.0 - v[b], rel=1e-9)
    for method in ("graphcut", "quadratic"):
        d = dense_depth(img, [[5, 5], [50, 35]], [10.0, 20.0], method=method, graph=g)
        assert abs(d.depth[0, 0] - 10.0) < 0.5 and abs(d.depth[-1, -1] - 20.0) < 0.5
    with pytest.raises(ValueError, match="method"):
        dense_depth(img, [[5, 5]], [1.0], method="bp", graph=g)
