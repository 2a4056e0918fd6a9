"""Tests of xslit_fit.glc: GLC characteristic equation, types of GLC bundles, agreement with the two-slit fit."""

import numpy as np
import pytest
from xslit_rays import GLC_KINDS, cylinder_rays, glc_bundle, unit, xslit_rays

from xslit_fit import GLC, FitError, fit_glc, fit_two_slits, glc_type

# What the two-slit fit must say for each GLC type.
FIT_REASON = {
    "pinhole": "pencil (single centre of projection)",
    "pencil": "double root (one slit)",
    "pushbroom": "slit at infinity (pushbroom)",
    "orthographic": "parallel rays",
    "twisted_orthographic": "double root at infinity (twisted orthographic)",
    "bilinear": "complex roots",
}


@pytest.mark.parametrize("kind", sorted(GLC_KINDS))
@pytest.mark.parametrize("c", [(0.0, 0.0), (0.3, -0.2)])
def test_glc_type_of_generated_bundles_and_agreement_with_the_fit(kind, c):
    p, d = glc_bundle(kind, np.random.default_rng(len(kind)), c=c)
    assert glc_type(p, d) == kind
    fit = fit_two_slits(p, d)
    if kind == "xslit":
        assert fit
    else:
        assert not fit and fit.reason == FIT_REASON[kind]


def test_three_generators_give_the_characteristic_roots_of_the_model():
    # Generators in the model's own 2PP: (s, t) = (u, v) + K·(u, v). det(I + λK) = 0 gives
    # the slit depths λ = −1/k for the eigenvalues k of K.
    k = np.array([[0.4, 0.3], [0.1, -0.25]])
    uv = np.array([[0.0, 0.0], [1.0, 0.2], [-0.3, 0.9]])
    st = uv + uv @ k.T
    pts = np.c_[uv, np.zeros(3)]
    dirs = np.c_[st - uv, np.ones(3)]
    glc = GLC.from_rays(pts, dirs, plane_point=[0, 0, 0], plane_normal=[0, 0, 1], scale=1.0)
    expected = np.sort(-1.0 / np.linalg.eigvals(k).real)
    assert np.allclose(glc.depths(), expected)
    a, b, c = glc.coefficients
    assert (a / c, b / c) == pytest.approx((np.linalg.det(k), np.trace(k)))
    assert glc.type() == "xslit"
    # The slits found are met by all three generators.
    for slit in glc.slits():
        n = np.cross(dirs, slit.direction)
        assert np.max(np.abs(np.einsum("ij,ij->i", pts - slit.point, n))) < 1e-12


def test_exact_xslit_bundle_is_xslit_and_glc_slits_match_the_fit():
    rng = np.random.default_rng(3)
    s1 = (np.array([0.0, 0.0, -0.1]), np.array([1.0, 0.0, 0.0]))
    s2 = (np.array([0.2, -0.1, -0.8]), unit(np.array([0.3, 1.0, 0.0])))
    p, d = xslit_rays(s1, s2, 300, rng, span=0.3)
    d = np.where(d[:, 2:] > 0, d, -d)
    assert glc_type(p, d) == "xslit"
    glc = fit_glc(p, d)
    assert glc.residual < 1e-12
    fit = fit_two_slits(p, d)
    for got, want in zip(sorted(glc.slits(), key=lambda s: s.direction[1] ** 2), fit.slits):
        assert np.linalg.norm(np.cross(got.direction, want.direction)) < 1e-9
        assert np.linalg.norm(np.cross(got.point - want.point, want.direction)) < 1e-9


def test_cylinder_patch_is_an_xslit_whose_glc_depths_match_the_fit():
    p, d, _ = cylinder_rays(0.1, 0.6, roi=(300, 220, 340, 260))
    p, d = p.reshape(-1, 3), d.reshape(-1, 3)
    assert glc_type(p, d) == "xslit"
    glc = fit_glc(p, d)
    fit = fit_two_slits(p, d)
    z = np.sort(fit.slit_offsets(glc.origin))
    assert np.allclose(np.sort(glc.depths()), z, rtol=1e-2)


def test_coplanar_bundle_is_epi_and_validation():
    rng = np.random.default_rng(9)
    p = np.c_[rng.normal(size=(30, 2)), np.zeros(30)]
    d = unit(np.c_[rng.normal(size=(30, 1)), np.ones((30, 1)), np.zeros((30, 1))])
    assert glc_type(p, d) == "epi"
    with pytest.raises(FitError, match="points: expected at least 3 rays"):
        glc_type(p[:2], d[:2])
    with pytest.raises(FitError, match="points: expected 3 generator rays"):
        GLC.from_rays(p[:4], d[:4])
