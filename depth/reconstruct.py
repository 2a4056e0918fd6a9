"""Reconstruction of cubes from one mirror image: `reconstruct` returns a `Reconstruction`.

Pipeline: the exact ray map of every pixel (camera traced against the mirror alone) gives the
mirror region; `depth.measure` finds the coloured cubes there and outlines each front face to
sub-pixel precision; `depth.estimate` turns each face into a cube (depth, size, 3D centre) with
the chosen estimator. Cubes cut by the mirror's edge or by another cube are refused, with the
reason, rather than guessed.
"""

from __future__ import annotations

import contextlib
import functools
import itertools
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from depth.errors import DepthError
from depth.estimate import (EDGE_BIAS_PX, EDGE_BIAS_PX_BLURRED, EDGE_BIAS_PX_COMPRESSED, METHODS,
                            NO_SIDE_FACE_GAP_PX, NO_SIDE_FACE_GAP_PX_SHARP, SOLVER_MODULES, CubeEstimate,
                            FaceMeasurement, FailedEstimate, _covering, _silhouette_disagreement, at_common_size,
                            common_size_of, estimate_face, estimate_face_on_floor, estimate_faces_shape_prior,
                            expected_work, fused_from, with_size_std)
from depth.workers import SharedMemory, fork_chain, fork_helper, fork_map, import_in_background
from raytrace.scene import Cube

__all__ = ["ALL_METHODS", "CubeResult", "Refusal", "Reconstruction", "reconstruct", "check_image", "start_helper",
           "stop_helper", "helper_started"]

ALL_METHODS = METHODS + ("shape_prior", "exact_shape_prior")
DEFAULT_METHOD = "exact"
EXACT_METHODS = ("exact", "exact_shape_prior")
"""The methods whose faces `exact` fits (and whose edge misfit the results report)."""


@dataclass(frozen=True)
class CubeResult:
    """One recovered cube: the estimate, its distance from the mirror axis, and its face in pixels."""

    estimate: CubeEstimate
    depth: float
    depth_std: float
    corners_px: np.ndarray
    bbox: tuple
    edge_points: int

    @property
    def edge_misfit_px(self) -> float | None:
        """Rms distance (px) of the edge points from the fitted face: `exact`'s; None for the other methods."""
        return float(self.estimate.rms_residual) if self.estimate.method in EXACT_METHODS else None

    def to_dict(self) -> dict:
        """The per-cube keys of SETUP_FORMAT.md's result, plus diagnostics (added keys only)."""
        e = self.estimate
        return {
            "center": [float(x) for x in e.center],
            "size": float(e.size),
            "depth": float(self.depth),
            "front_face_center": [float(x) for x in e.front_face_center],
            "front_face_corners_px": [[float(u), float(v)] for u, v in self.corners_px],
            "aspect_ratio": float(e.aspect_ratio),
            "method": e.method,
            "uncertainty": {"depth": float(self.depth_std), "size": float(e.std.get("size", np.nan)),
                            "center": float(e.std.get("center", np.nan))},
            **({"uncertainty_scale": float(e.std["scale"])} if "scale" in e.std else {}),
            **({"size_set_aside": bool(e.size_set_aside)} if e.method == "exact_shape_prior" else {}),
            **({"uncertainty_from_setup": dict(e.setup_std)} if e.setup_std is not None else {}),
            "front_face_normal": [float(x) for x in e.normal],
            "local_xslit": e.xslit,
            "edge_points": int(self.edge_points),
            "edge_misfit_px": self.edge_misfit_px,
            "bbox_px": [int(x) for x in self.bbox],
        }


def _floor(mirror, method, cube_size, floor_height, floor_std):
    """`reconstruct`'s floor: (a point of it, its height's σ), or None without `floor_height`; a `DepthError`
    for a floor the arguments cannot have."""
    if floor_height is None:
        if floor_std is not None:
            raise DepthError("floor_std: the σ of a floor's height: give floor_height too")
        return None
    if not np.isfinite(floor_height):
        raise DepthError(f"floor_height: expected a height in metres along the mirror's axis, got {floor_height}")
    if method != "exact":
        raise DepthError(f"floor_height: cubes standing on a floor are fitted by method exact, not {method}")
    if cube_size is not None:
        raise DepthError("floor_height: the floor fixes each cube's size; give it or cube_size, not both")
    if floor_std is not None and not (np.isfinite(floor_std) and floor_std >= 0):
        raise DepthError(f"floor_std: expected the σ of the floor's height in metres, >= 0, got {floor_std}")
    if not all(hasattr(mirror, key) for key in ("center", "axis")):
        raise DepthError("floor_height: the floor is placed along the mirror's axis; this mirror has none")
    return (np.asarray(mirror.center, dtype=np.float64) + float(floor_height) * np.asarray(mirror.axis),
            float(floor_std or 0.0))


@dataclass(frozen=True)
class Refusal:
    """A cube seen but not estimated, with the reason; `shadow_of_px`: for a blob refused as the shadow another cube
    read casts on the floor, the middle (u, v) px of that cube's front face (else None)."""

    bbox: tuple
    reason: str
    shadow_of_px: tuple | None = None

    def to_dict(self) -> dict:
        return {"bbox_px": [int(x) for x in self.bbox], "reason": self.reason,
                **({} if self.shadow_of_px is None else {"shadow_of_px": [float(x) for x in self.shadow_of_px]})}


@dataclass(frozen=True)
class Reconstruction:
    """All cubes of one image. `mirror_mask` (H, W) bool is the mirror region searched."""

    method: str
    cubes: list
    refused: list
    mirror_mask: np.ndarray = field(repr=False)
    blur_domain: str | None = None  # where the blur of blurred faces was taken to act; None: no face blurred
    floor: tuple | None = None  # (height along the mirror's axis from its centre, its σ) the cubes stood on; None: none
    setup_std: object = None  # the `depth.setup_error.SetupStd` carried into the cubes' σ; None: the setup exact


def _image_array(image, resolution) -> np.ndarray:
    """The image as an array, checked to be RGB of the setup's (W, H), not yet converted."""
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3:
        raise DepthError(f"image: expected an RGB image (H, W, 3), got shape {img.shape}")
    w, h = resolution
    if img.shape[:2] != (h, w):
        raise DepthError(f"image: expected {w}×{h} pixels (the setup's camera.resolution), "
                         f"got {img.shape[1]}×{img.shape[0]}")
    return img


def check_image(image, resolution, out: np.ndarray | None = None) -> np.ndarray:
    """Validate an RGB image array against the setup's (W, H); returns it as float64 in [0, 1], in `out` (a
    float64 array of its shape) where given."""
    img = _image_array(image, resolution)
    if img.dtype == np.uint8:
        return _from_8_bits(img, out)  # in [0, 1] as it is
    img = np.asarray(img, dtype=np.float64)
    if not (img.min() >= 0 and img.max() <= 1):  # NaN propagates through min and max, and fails both
        raise DepthError("image: expected values in [0, 1]")
    if out is None:
        return img
    np.copyto(out, img)
    return out


def _pixels(mask: np.ndarray) -> np.ndarray:
    """(N, 2) float64 (u, v) of a mask's pixels, in row-major order."""
    ys, xs = np.nonzero(mask)
    return np.column_stack([xs, ys]).astype(np.float64)


def _mask_of(pixels: np.ndarray, shape: tuple) -> np.ndarray:
    """The (H, W) bool mask of (N, 2) integer-valued (u, v) pixels (`_pixels` undone)."""
    out = np.zeros(shape, dtype=bool)
    px = pixels.astype(np.intp)
    out[px[:, 1], px[:, 0]] = True
    return out


def _bare(meas: FaceMeasurement) -> FaceMeasurement:
    """The measurement without its blob mask and image: what a worker process sends back (both are
    image-sized, and the parent's already)."""
    return replace(meas, blob_mask=None, image=None)


def _attached(meas: FaceMeasurement, blob_mask: np.ndarray, img: np.ndarray) -> FaceMeasurement:
    """The measurement with the blob mask and image `_bare` takes off (either may be another blob's)."""
    return replace(meas, blob_mask=blob_mask, image=img)


DESPECKLE_PX = 5
"""Median window for detecting cubes in JPEG images (their faces are then outlined on the image
itself). On the reconstruct bench's JPEG images it brought the measured front-face corners from
1.78 to 0.78 px off the truth (median; `python -m bench reconstruct`); 3 and 7 px windows did worse."""


def _from_8_bits(u8: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """An 8-bit image as float64 in [0, 1] (value / 255), into `out` where given: one image-sized array (75 MB
    at 2048×1536, faulted in afresh)."""
    return np.divide(u8, 255.0, out=out)


def despeckled(image: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """The image (float64 in [0, 1], or its 8-bit values) median-filtered per channel over `DESPECKLE_PX`
    (JPEG block and ringing artefacts break faces into fragments of slightly different colour), as float64,
    into `out` where given. A float image is filtered on its values rounded to 8 bits: those of an 8-bit
    image come back from its float64 conversion to the bit, so the two give the same."""
    u8 = image if image.dtype == np.uint8 else np.round(np.clip(image, 0.0, 1.0) * 255.0).astype(np.uint8)
    return _from_8_bits(cv2.medianBlur(np.ascontiguousarray(u8), DESPECKLE_PX), out)


FAINT_SIDE_BEYOND_PX = 1.5
"""How far (px) beyond a faint side face's outer edge (`FaceOutline.faint_side_px`) `_faint_sides_clear` looks
for another blob."""

FAINT_SIDE_NEIGHBOUR_SHARE = 0.5
"""Above this share of a side's points with another blob past its faint side face's outer edge (`FAINT_SIDE_BEYOND_PX`
on), `_faint_sides_clear` takes that face for the background before the other blob."""


def _faint_sides_clear(outline, blob_mask, blobs):
    """`outline` without each faint side face (`FaceOutline.faint_side_px`) whose outer edge is another blob's: over
    `FAINT_SIDE_NEIGHBOUR_SHARE` of the side's points, the pixel `FAINT_SIDE_BEYOND_PX` beyond that edge lies in a
    blob of `blobs` (every blob's pixels) that is not `blob_mask`. The look for a faint side face takes the first
    step of brightness within its reach beyond the side for the face's back edge: between two grey cubes before a
    light sky (holdout 1212 all grey s6, the cubes 7.4 px apart in the image) it read the sky between them as a
    side face of the left cube, its back edge the right cube's near edge; the left cube, turned to show such a face,
    came out 30.6 % near at −19.0 σ (JPEG; 31.3 % at −12.7 σ in PNG). Without that face, 25.8 % far at +0.6 σ (4.3 % at
    −0.1 σ), its σ 37 % (47 %) of the depth: a face 11 px wide whose side faces do not show. Over the 60 holdout runs
    and the reconstruct, lighting and on-floor benches, the other 84 readings of a faint side face all stand
    (ninety-ninth session)."""
    found = np.asarray(outline.faint_side_px, dtype=np.float64)
    kept = found.copy()
    height, width = blob_mask.shape
    for k in np.flatnonzero(found > 0.0):
        pts = outline.sides[k] + (found[k] + FAINT_SIDE_BEYOND_PX) * outline.normals[k]
        col = np.clip(np.round(pts[:, 0]).astype(int), 0, width - 1)
        row = np.clip(np.round(pts[:, 1]).astype(int), 0, height - 1)
        if np.mean(blobs[row, col] & ~blob_mask[row, col]) > FAINT_SIDE_NEIGHBOUR_SHARE:
            kept[k] = 0.0
    return outline if np.array_equal(kept, found) else replace(outline, faint_side_px=kept)


def _measurement(img, blob_mask, outline, face_px, channels, compressed, blobs=None):
    """What `estimate_face` takes from an outline: its edges, the silhouette beside it, the face's pixels. With
    `blobs` (every blob's pixels), a faint side face that ends at another blob is left out (`_faint_sides_clear`)."""
    from depth.measure import silhouette

    if blobs is not None:
        outline = _faint_sides_clear(outline, blob_mask, blobs)
    sil = silhouette(img, blob_mask, outline, channels=channels)
    no_gap = NO_SIDE_FACE_GAP_PX if compressed or outline.blurred else NO_SIDE_FACE_GAP_PX_SHARP
    backs, gaps = list(sil.sides), list(sil.gaps_px)
    # A faint side face (`FaceOutline.faint_side_px`), left out of the blob or in it with an outer edge too
    # faint for the silhouette's points: its outer edge is the back vertical edge the silhouette would have
    # shown, where the silhouette shows no face beside the other side (a cube shows at most one of its left
    # and right faces). The edge runs parallel to the side's points, that far out.
    for k in np.flatnonzero(outline.faint_side_px > 0.0):
        if sil.sides[k] is None and sil.sides[1 - k] is None and not sil.gaps_px[1 - k] > no_gap:
            backs[k] = outline.sides[k] + outline.faint_side_px[k] * outline.normals[k]
            gaps[k] = float(outline.faint_side_px[k])
    return FaceMeasurement(tuple(outline.sides), outline.corners_px, face_px, outline.edge_noise_px,
                           back_sides_px=tuple(backs), side_gaps_px=tuple(gaps), strip_px=tuple(outline.strip_px),
                           edge_bias_px=EDGE_BIAS_PX_COMPRESSED if compressed
                           else EDGE_BIAS_PX_BLURRED if outline.blurred else EDGE_BIAS_PX,
                           no_side_face_gap_px=no_gap, blob_mask=blob_mask, image=img)


SHADOW_MISFIT_PX = 0.45
"""`exact`'s edge misfit (rms px) above which a face found without colour is taken for a shadow (where it is over
`SHADOW_MISFIT_SCATTER` times its edges' own scatter too): the outlines of cube shadows on a floor fit a square
face to 0.54–0.80 px (lighting bench, floor case), those of grey, white and black cubes to 0.03–0.32 px (its
grey case)."""


BLOB_OUTSIDE_SHARE = 0.025
"""Share of a blob found without colour that may lie more than a pixel outside the silhouette of the
cube read from it (`_silhouette_disagreement`, blob pixels only). Measured over the 247 readings of grey,
white and black faces that passed the edge misfit test on the lighting bench (sun-front grey, the floor
scenes) and on the holdouts (seeds 7070, 8080, 9090, all grey, PNG and JPEG): 241 have none, two cubes
0.2 and 0.9 %; four readings, 50–58 %, are holdout 7070 scene 2's two floor shadows (PNG and JPEG),
refused anyway as lying inside the mirror. Over it: the white cube of the lighting bench's floor-grey
scene 5 whose front face, as bright as the floor it stands on, was taken for background, found as the
upper part of its left side face (cut off where no edge closed it) with a piece of its top face, and
read as a cube 0.93 m away, its face turned to its rays (4.5 %: the top face reaches past the side face
read as the front; invented once that image's blur was read as linear, `BLUR_EVIDENCE_MARGIN`)."""


SHADOW_MISFIT_SCATTER = 1.1
"""The edge misfit up to which a face found without colour is not taken for a shadow is at least this many times
its edges' own scatter (`FaceMeasurement.edge_noise_px`, each side's own line or curve fitted alone): no square
fits edge points better than they scatter from point to point. A light grey face 0.04 of sRGB from the floor
behind it, a path tracer's noise on it, has its sides read 0.44–0.47 px from their own fits (holdout 3030 s7/4,
PNG and all grey), and was refused at 0.47–0.60 px misfit, read 0.4–3.8 % off. Floor shadows misfit more than
their scatter, or miss smoothly along both sides (`_curved_sides`): of the 823 collected readings (see
`SHADOW_CURVED_SIDE_PX`), those of shadows under 1.1 times their scatter and over `SHADOW_MISFIT_PX` bow on both
sides but one (3030 all grey JPEG s3, 0.99 times), which the later tests refuse."""

SHADOW_CURVED_SIDE_PX = 0.3
"""Rms misfit (px) over which each of the left and right sides of a face found without colour must miss
`exact`'s upright face, smoothly (`SHADOW_CURVED_DW`), for `_shadow_reason` to take it for a shadow on the
floor. Such a shadow's left and right sides are the shadows of the cube's upright edges: lines on the floor,
which the mirror images as curves where an upright edge images as the line the model draws, so the model
misses both along their length. Of the 823 readings of regions without colour that reached `_shadow_reason` on
the lighting bench (its floor and sun-front grey scenes) and on the holdouts (seeds 3030–9090, PNG, all grey and
all grey in JPEG; scratch `/tmp/d80/collect2.py`, eightieth session), 538 within 10 % of a true cube, the 59 with
both sides past both limits all lie 47–87 % from any cube: floor shadows, among them holdout 5050 s0's, which
the edge misfit let through (0.38 px rms; its sides 0.38 and 0.46 px, Durbin–Watson 0.22 and 0.10). The real
cube nearest to the limits: sides 0.37 px at 0.43 and 0.27 px at 0.05 (the lighting bench's sun-front grey s0)."""

SHADOW_CURVED_DW = 0.3
"""Durbin–Watson statistic (`CubeEstimate.side_misfits`) under which a side's misfit runs smoothly along it: the
pixel noise of an edge read right gives 0.5–2 (its points a pixel apart share some of it). A real cube's side read
off along part of its length (a shadow's edge across it) can give less, but on the readings measured (see
`SHADOW_CURVED_SIDE_PX`) never both sides past both limits at once."""

SHADOW_CURVED_MIN_POINTS = 8
"""Fewest edge points of a side for its Durbin–Watson statistic to count in `_curved_sides`."""

SHADOW_MISFIT_REASON = "no colour, and its outline is no square face's"
"""How `_shadow_reason`'s refusals for an edge misfit over `SHADOW_MISFIT_PX` and for bowed sides
(`_curved_sides`) begin: `_faces` reads neither at the fainter steps."""


FLAT_FACE_MIN_PX = 8
"""Pixels a top face must show more than a pixel in from its edges (and the front face too) for
`_flat_region_reason` to compare their brightness: the merged top faces of the holdout floor shadows read
as cubes show 14–39 such pixels (one, 3–4 px, is not judged)."""

FLAT_STEP_Z = 3.0
"""Step (in standard errors of the two faces' mean colours, the largest over the channels) under which a
top face is taken to show its front face's brightness (`_flat_region_reason`). The holdout floor shadows'
merged top faces step 1.4–2.1. Of the 174 readings of real grey, white and black cubes on the holdouts
(seeds 3030–9090, odd scenes grey and all grey, PNG and JPEG) with a top face to judge and an unclipped
front face, those that took the front face's upper part for a merged top face (17–19 % off) step 0.5–1.8
(one of the two cubes kept by a side face's step); the others 5.0 and more, 9.0 and more within 5 % of the
truth."""

FLAT_CLIPPED = 250.0 / 255.0
"""A front face whose mean reaches this in a channel is taken as clipped: a white cube's faces in the sun
all read 1.0, and their equal brightness says nothing of their light. (A clipped face beside an unclipped
front face differs from it anyway.)"""

FLAT_TOP_COS = 0.5
"""A cube's end face (its normal along the mirror axis) is its top face where that normal lies within 60°
of the camera's up (the world's, as the setup gives it)."""

FLAT_REGION_REASON = "no colour, and the faces read show one brightness"
"""How `_flat_region_reason`'s refusal begins."""

GROWN_PART_MARGIN_PX = 5
"""A detection grown across faint edges may touch another grey blob only where that blob lies within the grown
blob's bounds widened by this (px) on each side: a darker face of the same cube (`_faces`' `regrown`)."""

SAME_FACE_REASON = "the same face as the cube read at"
"""How `_one_per_face`'s refusal begins."""


INTERNAL_ERROR_REASON = "internal error while reading this face"
"""How a face's refusal begins where reading it raised an exception no check expects (`_guarded`)."""


def _guarded(task, refused):
    """`task` (one face's reading) with an exception it raises turned into `refused(reason, *its arguments)`, the
    reason naming the exception; a `DepthError` (the caller's input) is raised as it is. One face's failure then
    costs that face, not the image's other cubes: a floor shadow's refit in an unseen holdout render ran off to an
    infinite size, and the whole image raised a `RaytraceError` about a "size" no setup had given (`depth.estimate`
    now takes such a pose for no fit)."""
    @functools.wraps(task)
    def run(*args, **kwargs):
        try:
            return task(*args, **kwargs)
        except DepthError:
            raise
        except Exception as err:  # (any failure of one face's reading is that face's refusal)
            return refused(f"{INTERNAL_ERROR_REASON} ({type(err).__name__}: {err}): please report it", *args)
    return run


def _one_per_face(results):
    """`results` ((estimate, outline, reason or None, bbox, and anything else) per measured face) with every face
    read where another was read already (the centre of either's outline within the other's) refused, the one with the
    lower edge misfit kept: two darker faces of one white cube, each grown across faint edges into its whole
    front face (`_faces`' `regrown`)."""
    kept, out = [], []
    for est, outline, reason, bbox, *reading in results:
        if not reason:
            centre = np.mean(outline.corners_px, axis=0)
            for k in kept:
                other = out[k][1]
                other_centre = np.mean(other.corners_px, axis=0)
                if _inside(centre, other.corners_px) or _inside(other_centre, outline.corners_px):
                    if est.rms_residual < out[k][0].rms_residual:  # this one kept, the other refused
                        (est, outline, reason, bbox, *reading), out[k] = out[k], (est, outline, None, bbox, *reading)
                        centre, other_centre = other_centre, centre
                    reason = (f"{SAME_FACE_REASON} ({other_centre[0]:.0f}, {other_centre[1]:.0f}) px from "
                              "another blob")
                    break
            else:
                kept.append(len(out))
        out.append((est, outline, reason, bbox, *reading))
    return out


def _inside(point, corners) -> bool:
    """Whether `point` (2,) lies inside (or on) the quadrilateral `corners` (4, 2), in pixels."""
    return cv2.pointPolygonTest(np.asarray(corners, dtype=np.float32).reshape(-1, 1, 2),
                                (float(point[0]), float(point[1])), False) >= 0


def _face_colours(img, rays, cube: Cube, window) -> list:
    """Per face of `cube` (`raytrace.scene.FACE_AXES`), the colour the image shows where its reflected rays
    enter the cube through that face, more than a pixel in from every edge (the face's label mask eroded
    by a 3×3 square): (pixel count, mean (C,), standard deviation (C,)); the count 0 where there are none.
    `img` is the (H, W, C) image, `window` (row0, row1, col0, col1) bounds the pixels tested."""
    r0, r1, c0, c1 = window
    yy, xx = np.mgrid[r0:r1, c0:c1]
    origins, directions = rays(np.column_stack([xx.ravel(), yy.ravel()]).astype(np.float64))
    faces = cube.entry_faces(origins, directions).reshape(yy.shape)
    window_img = img[r0:r1, c0:c1]
    out = []
    for f in range(6):
        inner = cv2.erode((faces == f).view(np.uint8), np.ones((3, 3), np.uint8), borderType=cv2.BORDER_CONSTANT,
                          borderValue=0).view(bool)
        values = window_img[inner]
        out.append((len(values), values.mean(axis=0), values.std(axis=0)) if len(values) else (0, None, None))
    return out


def _flat_region_reason(img, rays, est: CubeEstimate, blob_mask, up, sky) -> str | None:
    """Why a cube read from a region without colour is taken for a flat mark, or None.

    A cube's top face takes the light of the whole sky, its upright faces half of it and the ground's,
    and its faces are told apart by their brightness. A shadow on a floor that happens to be a
    quadrilateral is one region of one brightness; read as a cube's face with its top face merged (its
    outline then fits a square face as well as a grey cube's: 0.21–0.41 px on the holdouts), the top face
    shows the front face's brightness. Where the pose shows a top face (by the camera's up, `sky`; see
    `FLAT_TOP_COS`) over `FLAT_FACE_MIN_PX` pixels, no face it shows differs from the front face by
    `FLAT_STEP_Z` standard errors or more, and the front face is not clipped (`FLAT_CLIPPED`), the region
    is refused. Upright faces alone do not count: two of them turned from the sun take the same sky light.
    Nor do bottom faces, lit by the ground alone, which can light one as an upright face in shade is
    (holdout 4040 all grey, scene 0, cube 2: a bottom face within 3 standard errors of its front face).
    A real cube read with its front face's upper part taken for a merged top face is refused so too: that
    reading is wrong either way, and a cube whose top face is as bright as what lies behind it (no part
    of the blob) looks like a shadow."""
    if up is None or sky is None or blob_mask is None:  # (`img`: float values in [0, 1])
        return None
    x, y, bw, bh = cv2.boundingRect(blob_mask.view(np.uint8))  # (np.nonzero over the image-sized mask: 20×)
    h, w = blob_mask.shape
    window = (max(y - 2, 0), min(y + bh + 2, h), max(x - 2, 0), min(x + bw + 2, w))
    cube = _cube(est, up)  # local axes: up (faces 0, 1), across, the front face's normal (face 4)
    tops = [f for f in (0, 1) if cube.face_normals[f] @ sky > FLAT_TOP_COS]
    if not tops:
        return None
    colours = _face_colours(img, rays, cube, window)
    n_front, front_mean, front_std = colours[4]
    if n_front < FLAT_FACE_MIN_PX or np.max(front_mean) >= FLAT_CLIPPED:
        return None
    steps = {}
    for f, (n, mean, std) in enumerate(colours):
        if f == 4 or n < FLAT_FACE_MIN_PX:
            continue
        se = np.sqrt(std**2 / n + front_std**2 / n_front)
        steps[f] = float(np.max(np.abs(mean - front_mean) / np.maximum(se, 1e-12)))
    if tops[0] not in steps or max(steps.values()) >= FLAT_STEP_Z:
        return None
    return (f"{FLAT_REGION_REASON}: its top face would show its front face's colour over {colours[tops[0]][0]} px "
            f"(a step of {steps[tops[0]]:.1f} standard errors, under {FLAT_STEP_Z:g}) where a cube's top face "
            f"takes the sky's light: a flat mark (a shadow?)")


def _shadow_reason(rays, meas, est, cube_size, up, img=None, sky=None) -> str | None:
    """Why a face found without colour is not taken for a cube, or None.

    A grey, white or black cube and a shadow on a grey floor look alike: both are a region of
    another brightness than the background around it. A cube's shadow, though, is a hexagon, not the
    image of a square face: where `exact`'s edge misfit exceeds `SHADOW_MISFIT_PX` and `SHADOW_MISFIT_SCATTER`
    times the edges' own scatter (the other methods are checked with `exact`), the region is refused. A shadow
    that happens to be a quadrilateral (a sun along a face) is not told from a grey cube by that. Nor is a
    fragment of a larger object whose edges happen to fit a square: where over `BLOB_OUTSIDE_SHARE` of the
    blob lies outside the cube read, more than a pixel deep, the cube does not explain the blob and is refused.
    Given the image (`img`) and the camera's up (`sky`), a quadrilateral read with a merged top face of its
    front face's brightness is refused as one flat region (`_flat_region_reason`). One whose left and right
    sides both miss the upright face smoothly along their length is a shadow on the floor (`_curved_sides`)."""
    check = est if est.method == "exact" else estimate_face(rays, meas, method="exact", cube_size=cube_size, up=up)
    if not check:
        return f"no colour and no square face: {check.reason} (a shadow?)"
    limit = max(SHADOW_MISFIT_PX, SHADOW_MISFIT_SCATTER * meas.edge_noise_px)
    if check.rms_residual > limit:
        return f"{SHADOW_MISFIT_REASON} (edge misfit {check.rms_residual:.2f} px > {limit:.2f} px): a shadow?"
    if meas.blob_mask is not None:
        n_blob = int(np.count_nonzero(meas.blob_mask))
        outside = _silhouette_disagreement(rays, meas.blob_mask, blob_only=True)(_cube(check, up))
        if outside > BLOB_OUTSIDE_SHARE * n_blob:
            return (f"no colour, and {outside} of its {n_blob} pixels lie outside the cube read from it "
                    f"(> {BLOB_OUTSIDE_SHARE:.1%}): a fragment of a larger object?")
    if img is not None and (flat := _flat_region_reason(img, rays, check, meas.blob_mask, up, sky)):
        return flat
    if curved := _curved_sides(check):
        return f"{SHADOW_MISFIT_REASON}: {curved}: a shadow on the floor?"
    return None


def _curved_sides(est: CubeEstimate) -> str | None:
    """Why `est`'s left and right sides are no upright edges' images, or None (`SHADOW_CURVED_SIDE_PX`)."""
    sides = est.side_misfits[:2]
    if len(sides) < 2 or not all(n >= SHADOW_CURVED_MIN_POINTS and rms > SHADOW_CURVED_SIDE_PX
                                 and dw < SHADOW_CURVED_DW for n, rms, dw in sides):
        return None
    return ("both its left and right sides miss an upright face's edges smoothly along their length (rms "
            f"{sides[0][1]:.2f} and {sides[1][1]:.2f} px > {SHADOW_CURVED_SIDE_PX} px, Durbin–Watson "
            f"{sides[0][2]:.2f} and {sides[1][2]:.2f} < {SHADOW_CURVED_DW})")


BENT_SIDE_PX = 0.5
"""Rms misfit (px) of the top or bottom side of `exact`'s front face over which the face's union with a touching
part of its blob of the same colour is read as well (`_bent_side`, `_faces`). Read alone, the shadowed part of
holdout 1111 s2/3's front face misses its bottom side by 0.73 px (0.79 px in JPEG; 0.76 px on our renderer's image of
it, `tests/depth/test_shadow_across_face.py`), and 1313 s4/1's by 1.20 px. A top or bottom side is short and often
borders a merged top or bottom face, so faces read right pass 0.5 px too: 110 of the 1610 readings of the holdouts
(seeds 1010–9090, 4 runs each; ninety-eighth session), 109 of them of a true cube. Each costs one more fit, and only
readings that disagree with their union's move (`RIVAL_SIGMAS`)."""

BENT_SIDE_MIN_POINTS = 8
"""Fewest edge points of a side for `_bent_side` to judge it."""

RIVAL_SIGMAS = 3.0
"""How far apart (σ of their depths' difference) a face's reading and its union's must lie to disagree. Of the 77
unions read over the holdouts' 60 runs and the reconstruct, lighting and on-floor benches (ninety-eighth session), 6
disagreed: holdout 1111 s2/3 and 1313 s4/1, in PNG and JPEG, whose faces read alone were 14.2–14.3 % and 8.8–8.9 % off
at +5.2 to +12.0 σ, and whose unions fit better and read 1.8–4.7 % and 0.3–0.9 % off, within 0.5 σ once their σ
covers the other reading; and the reconstruct bench's s11/1 with noise (and its `exact_shape_prior` fit), whose face
read alone fits better (0.293 against 0.294 px) and stands, 8.8 % off, at +0.4 σ where it was at +1.2 σ."""


def _bent_side(est: CubeEstimate) -> bool:
    """Whether `exact`'s square misses the top or bottom side of the face read by over `BENT_SIDE_PX` rms."""
    return any(n >= BENT_SIDE_MIN_POINTS and rms > BENT_SIDE_PX for n, rms, _ in est.side_misfits[2:4])


def _inside_mirror_reason(mirror, est: CubeEstimate) -> str | None:
    """Why a cube cannot be where the estimate puts it, because that is inside the mirror, or None.

    The image shows what the mirror's outer surface reflects; a cube whose centre lies inside the solid
    the mirror bounds (`contains`; mirrors without it are not checked) is seen by no reflection. A face
    fitted to something that is no square face can still come out with a small misfit by turning
    nearly edge-on to its rays, the cube behind it then reaching back into the mirror: two floor shadows
    of an unseen holdout render (seed 7070, scene 2) were read as cubes 3.3 and 3.5 mm across, their
    faces 54–56° from their rays, their centres 14 and 10 mm inside a mirror of radius 141 mm; every
    real cube of the benches lies outside, its face within 39° of its ray."""
    contains = getattr(mirror, "contains", None)
    if contains is None or not contains(est.center[None])[0]:
        return None
    where = ""
    if hasattr(mirror, "radius"):  # (`distance_to_axis` every mirror here has: the result's depth uses it)
        r = float(mirror.distance_to_axis(est.center[None])[0])
        where = f", {r * 1e3:.1f} mm from the axis of a mirror of radius {mirror.radius * 1e3:.1f} mm"
    return f"its centre would lie inside the mirror{where}, where no reflection reaches"


DIRECT_VIEW_IN_MIRROR = 0.5
"""Share of a cube's direct image (the hull of its vertices seen straight by the camera) lying on the
mirror above which, with the cube nearer than the mirror, it is taken to stand between them."""

DIRECT_VIEW_SEEN = 0.25
"""Share of the mirror pixels such a cube would hide that must belong to some detected blob for it to
be kept: a cube standing there would itself show in the mirror region, as a blob."""


def _front_face_px(est: CubeEstimate, camera, mirror, measured: np.ndarray) -> np.ndarray:
    """The image of the front face's corners (4, 2) px, in the order of the `measured` outline's (top-left, top-right,
    bottom-right, bottom-left): where `exact`'s pose puts them (`CubeEstimate.front_face_corners`), each reflected by
    the exact law (`raytrace.truth.reflection_pixels`); the measured corners where the estimate has none (another
    estimator) or a corner has no reflection. The measured outline is the blob's where a top, bottom or side face
    merged with the front face was modelled (its corners are the silhouette's, pixels off the front face's), and its
    corners meet fitted lines, not the fitted face: over the reconstruct bench's clean, JPEG and Mitsuba images the
    pose's corners lie 0.09 px from the truth's (median; 90th percentile 0.48 px, max 5.5) against 0.27 px (2.6,
    8.3) for the measured ones; over holdout 3030's, 0.22 px (1.5, 12.2) against 0.85 px (8.9, 31.1)."""
    from raytrace.mirror import CylinderMirror
    from raytrace.truth import reflection_pixels
    central = getattr(camera, "is_central", False)
    if est.front_face_corners is None or not isinstance(mirror, CylinderMirror) or not central:
        return measured
    px, ok = reflection_pixels(camera, mirror, est.front_face_corners)
    if not ok.all() or not np.all(np.isfinite(px)):
        return measured
    # the order of the measured corners: the one-to-one assignment of least total distance (of the 24)
    d = np.linalg.norm(px[:, None, :] - np.asarray(measured)[None, :, :], axis=2)
    best = min(itertools.permutations(range(4)), key=lambda p: sum(d[p[k], k] for k in range(4)))
    return px[list(best)]


def _cube_vertices(est: CubeEstimate, up) -> np.ndarray:
    """(8, 3) float64: the cube's corners, its front face along `est.normal` and an edge along `up`
    (the mirror axis; any direction across the normal when None)."""
    return _cube(est, up).vertices()


def _cube(est: CubeEstimate, up) -> Cube:
    """The estimated cube (`raytrace.scene.Cube`): see `_cube_vertices`."""
    n = est.normal / np.linalg.norm(est.normal)
    u = np.array([0.0, 1.0, 0.0]) if up is None else np.asarray(up, dtype=np.float64)
    u = u - (u @ n) * n
    if np.linalg.norm(u) < 1e-9:
        u = np.cross(n, [1.0, 0.0, 0.0])
    u = u / np.linalg.norm(u)
    return Cube(est.size, est.center, np.column_stack([u, np.cross(n, u), n]))


CAST_SHADOW_IOU = 0.75
"""Overlap (intersection over union, in the image) of a blob with the shadow another cube read casts on the floor from
which the blob is taken for that shadow (`_cast_shadow_overlaps`): their outlines within about a pixel of each other
all round (two regions 7 px wide a pixel apart overlap by 6 / 8; the floor shadows the unseen holdouts read as cubes
were 7–12 px wide). 13 of those 15 shadows overlap their own caster's shadow by 0.78–0.94, each naming the cube whose
shadow under the renderer's sun lies within 1.7 px of it; 1414 s5's, in its PNG runs, by 0.41 (its caster, the black
cube, read 15 % large, σ 22 %), and another cube's by 0.68. The real cubes darker than the floor beside them overlap the
shadow of another cube read by at most 0.59 on the holdouts (1414 s0/4), 0.53 on the reconstruct bench, and under 0.4
on the lighting and on-floor benches (`exact`'s readings, ninety-seventh session). With each caster taken at sizes
within its σ too (`_caster_readings`; hundred-and-second session), the shadows of the 68 holdout runs (seeds 1717 and
1818 too) overlap their casters' by 0.83–0.96, 1414 s5's and 1818 all grey s2's among them (those two read as cubes
before: their casters read 10–15 % large, their shadows at those sizes overlapping by 0.41 and 0.64), and the real
cubes darker than the floor beside them another cube's by at most 0.70 (7070 PNG s2/3, a purple cube, against a cube
read 34 ± 22 mm across taken at 68 mm); 0.53 on the reconstruct bench, under 0.55 on the lighting bench, and 0.64 on
the on-floor bench (a cube standing on the floor, against one read 55.8 ± 5.0 mm taken at 45.8 mm)."""

CAST_SHADOW_SAMPLES = 16
"""Points per side of a shadow's outline on the floor reflected into the image (`_cast_shadow_outlines`): the
mirror images the outline's straight sides as curves."""

CAST_SHADOW_RAYS = 2048
"""Pixels of a blob, evenly spread, whose rays give the middle of its floor region (`_cast_shadow_overlaps`): all of
any shadow the benches read as a cube (the largest, 21 × 48 px), a sample of a large cube's face."""

CAST_SHADOW_RING_PX = (2, 6)
"""The band about a blob (px from it, inner and outer) whose pixels outside every blob are the floor beside it, which
a shadow is darker than (`_darker_than_beside`)."""


def _floor_point(mirror, floor):
    """A point of the floor shadows fall on: `reconstruct`'s `floor` where given, else the plane square to the
    mirror's axis at its lower end (the floor it stands on, where `simulate`'s ground lies); None for a mirror
    with no axis."""
    if floor is not None:
        return np.asarray(floor[0], dtype=np.float64)
    if not all(hasattr(mirror, key) for key in ("center", "axis", "height")):
        return None
    return np.asarray(mirror.center, dtype=np.float64) - 0.5 * float(mirror.height) * np.asarray(mirror.axis)


def _window(mask: np.ndarray, margin: int):
    """(slice of rows, slice of columns) of `mask`'s bounding box grown by `margin` px, within the image."""
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    h, w = mask.shape
    return (slice(max(rows[0] - margin, 0), min(rows[-1] + margin + 1, h)),
            slice(max(cols[0] - margin, 0), min(cols[-1] + margin + 1, w)))


def _darker_than_beside(img, blob, blobs) -> bool:
    """Whether `blob` ((H, W) bool) is darker in every channel of `img` than the pixels beside it
    (`CAST_SHADOW_RING_PX`) outside every blob (`blobs`, (H, W) bool), as a shadow is than the lit floor about it;
    False where fewer than 8 pixels lie beside it."""
    inner, outer = CAST_SHADOW_RING_PX
    if not blob.any():
        return False
    box = _window(blob, outer + 1)
    own = blob[box].view(np.uint8)
    ring = (cv2.dilate(own, np.ones((2 * outer + 1,) * 2, np.uint8))
            & ~cv2.dilate(own, np.ones((2 * inner + 1,) * 2, np.uint8))).view(bool) & ~blobs[box]
    if np.count_nonzero(ring) < 8:
        return False
    window = img[box]
    return bool(np.all(window[blob[box]].mean(axis=0) < window[ring].mean(axis=0)))


def _cast_shadow_outlines(camera, mirror, cast, floor_point, up, areas=None) -> list:
    """Per (caster (`Cube`), light (3,)) of `cast`: the outline (M, 2) px of the shadow the caster casts on the floor
    (through `floor_point`, square to `up`) under a distant light travelling along that direction, reflected into
    the image; None where that light comes from below, where part of the outline has no reflection, or where the
    shadow's area on the floor lies outside `areas` ((least, most) m², if given). (One reflection solve for them
    all: 2.5 ms a call for a few points, 30 ms for 6500.)"""
    from raytrace.truth import reflection_pixels
    rings = []
    for caster, light in cast:
        if light @ up >= 0:
            rings.append(None)
            continue
        v = caster.vertices()
        on_floor = v + (((floor_point - v) @ up) / (light @ up))[:, None] * light
        across = np.cross(up, light)
        across /= np.linalg.norm(across)
        along = np.cross(across, up)
        flat = np.column_stack([(on_floor - floor_point) @ across, (on_floor - floor_point) @ along])
        hull = cv2.convexHull(flat.astype(np.float32))
        if areas is not None and not areas[0] <= cv2.contourArea(hull) <= areas[1]:
            rings.append(None)
            continue
        hull = hull.reshape(-1, 2).astype(np.float64)
        s = np.arange(CAST_SHADOW_SAMPLES) / CAST_SHADOW_SAMPLES
        ring = (hull[:, None, :] + s[None, :, None] * (np.roll(hull, -1, axis=0) - hull)[:, None, :]).reshape(-1, 2)
        rings.append(floor_point + ring[:, :1] * across + ring[:, 1:] * along)
    shown = [r for r in rings if r is not None]
    if not shown:
        return rings
    px, ok = reflection_pixels(camera, mirror, np.concatenate(shown))
    out, start = [], 0
    for ring in rings:
        if ring is None:
            out.append(None)
            continue
        part, good = px[start:start + len(ring)], ok[start:start + len(ring)]
        start += len(ring)
        out.append(part if good.all() and np.all(np.isfinite(part)) else None)
    return out


def _overlap(blob, n_blob: int, outline) -> float:
    """Intersection over union of `blob` ((H, W) bool, `n_blob` pixels) and the polygon `outline` (M, 2) px filled on
    the pixel grid (the part of it within the image)."""
    h, w = blob.shape
    lo = np.maximum(np.floor(outline.min(axis=0)).astype(int) - 1, 0)
    hi = np.minimum(np.ceil(outline.max(axis=0)).astype(int) + 2, (w, h))
    if np.any(hi <= lo):
        return 0.0
    polygon = np.zeros((hi[1] - lo[1], hi[0] - lo[0]), np.uint8)
    cv2.fillPoly(polygon, [np.round(outline - lo).astype(np.int32)], 1)
    inside = np.count_nonzero(polygon.view(bool) & blob[lo[1]:hi[1], lo[0]:hi[0]])
    return inside / (n_blob + np.count_nonzero(polygon) - inside)


CAST_SHADOW_SIZE_SPAN = 2.0
"""How far (in σ of its size) a caster's size is taken as possibly off for its shadow (`_caster_readings`)."""

CAST_SHADOW_SIZE_STEPS = 17
"""Sizes of a caster whose shadows are compared with a blob (`_caster_readings`), evenly over ±`CAST_SHADOW_SIZE_SPAN`
σ of its size read."""


def _caster_readings(est: CubeEstimate, up) -> list:
    """The cube `est` reads (`_cube`) at `CAST_SHADOW_SIZE_STEPS` sizes evenly within ±`CAST_SHADOW_SIZE_SPAN` σ of its
    size (`est.std["size"]`), the size read first and the others in order of their distance from it, each moved as its
    fit moves with its size, to first order (the slope of the centre on the size in `est.first_order_cov`): a cube
    whose depth the image fixes poorly casts its shadow where its true size does, not where its size read does. The
    cube read alone where that covariance or σ is missing; no size under a quarter of the size read."""
    cube = _cube(est, up)
    cov, sd = est.first_order_cov, float(est.std.get("size", np.nan))
    if cov is None or not np.isfinite(sd) or sd <= 0 or not cov[3, 3] > 0:
        return [cube]
    slope = np.asarray(cov[:3, 3]) / cov[3, 3]
    steps = sd * np.linspace(-CAST_SHADOW_SIZE_SPAN, CAST_SHADOW_SIZE_SPAN, CAST_SHADOW_SIZE_STEPS)
    steps = steps[np.argsort(np.abs(steps), kind="stable")]
    return [Cube(est.size + d, est.center + d * slope, cube.rotation) for d in steps if est.size + d >= 0.25 * est.size]


CAST_SHADOW_AREA_RATIO = 2.0
"""Factor either way beyond which a shadow's area on the floor differs from that of the blob's floor region (the
convex hull of its pixels' floor points) for `_cast_shadow_overlaps` to leave it out unreflected: the two cannot
overlap by `CAST_SHADOW_IOU` then. (An overlap of 0.75 needs their areas in the image within 4/3 of each other; the
mirror's map of the floor about the blob is nearly affine, and the hull of the pixel centres leaves out half a
pixel all round: 15 % of a shadow 10 × 20 px.) A real cube's face whose pixels' rays meet the floor meets it far
behind the cube, over an area many times a cube's shadow: on the reconstruct bench's s03 (five such faces, four
casters each) the reflection of every reading's shadow took 90 ms."""


def _cast_shadow_overlaps(camera, mirror, rays, blob, casters, floor_point, up) -> list:
    """How far `blob` ((H, W) bool) is the shadow each of `casters` casts on the floor through `floor_point`
    (`_floor_point`): per caster (a list of cubes, its readings: `_caster_readings`, the reading itself first), (the
    greatest overlap (intersection over union) of the blob with the shadow of one of its readings, the size of its
    first reading whose shadow overlaps the blob by `CAST_SHADOW_IOU` or more, else of the one overlapping most), (0,
    None) where none casts one there. All so for a mirror with no axis, or a camera with no centre. A shadow whose area
    on the floor differs from the blob's floor region's by over `CAST_SHADOW_AREA_RATIO` either way is not reflected
    into the image: it overlaps by 0.

    A cube floating over the floor casts its shadow there, apart from it: a dark region that may be a clean
    quadrilateral too small for its sides' curvature or a top face to show it lies flat (unseen holdouts 1010 s2,
    1111 s2, 1313 s0 and s2: read as cubes 4–8 mm across). Where most of the blob's rays meet the floor ahead, the
    light that would cast it from a cube read is the one along the line from that cube's centre to the middle of
    the blob's floor region (a cube's shadow, centrally symmetric, is centred on its centre's); the shadow the cube
    then casts is reflected into the image."""
    from raytrace.mirror import CylinderMirror
    none = [(0.0, None)] * len(casters)
    if floor_point is None or up is None or not casters or not isinstance(mirror, CylinderMirror) or not getattr(
            camera, "is_central", False) or not blob.any():
        return none
    up = np.asarray(up, dtype=np.float64)
    rows, cols = _window(blob, 0)
    ys, xs = np.nonzero(blob[rows, cols])
    n_blob = len(xs)
    some = np.linspace(0, n_blob - 1, min(n_blob, CAST_SHADOW_RAYS)).astype(int)  # (all of a shadow's pixels)
    points, directions = rays(np.column_stack([xs[some] + cols.start, ys[some] + rows.start]).astype(np.float64))
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((floor_point - points) @ up) / (directions @ up)
    ahead = np.isfinite(t) & (t > 0)
    if ahead.sum() <= 0.5 * len(t):
        return none
    on_floor = points[ahead] + t[ahead, None] * directions[ahead]
    centre = on_floor.mean(axis=0)
    across = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 0.0, 1.0])
    across /= np.linalg.norm(across)
    flat = np.column_stack([(on_floor - centre) @ across, (on_floor - centre) @ np.cross(across, up)])
    area = cv2.contourArea(cv2.convexHull(flat.astype(np.float32)))
    readings = [cube for caster in casters for cube in caster]
    areas = (area / CAST_SHADOW_AREA_RATIO, area * CAST_SHADOW_AREA_RATIO)
    shadows = iter(_cast_shadow_outlines(camera, mirror, [(cube, centre - cube.center) for cube in readings],
                                         floor_point, up, areas))
    out = []
    for caster in casters:
        overlaps = [(0.0 if shadow is None else _overlap(blob, n_blob, shadow), cube.size)
                    for cube, shadow in zip(caster, shadows)]
        best = max(overlaps, key=lambda o: o[0], default=(0.0, None))
        first = next((size for overlap, size in overlaps if overlap >= CAST_SHADOW_IOU), best[1])
        out.append((best[0], first) if best[0] > 0 else (0.0, None))
    return out


def _direct_view_reason(camera, mirror, est: CubeEstimate, mirror_region, blobs, up, own=None) -> str | None:
    """Why a cube is not where the estimate puts it, because the camera would see it there, or None.

    The image is of reflections: a cube standing between the camera and the mirror would hide part of
    the mirror and show there itself, as a blob of the mirror region. Where the estimate puts a cube so
    (over `DIRECT_VIEW_IN_MIRROR` of its direct image on the mirror, its centre nearer than the mirror
    along its ray) and under `DIRECT_VIEW_SEEN` of the pixels it would hide belong to any detected blob,
    the face was no cube's reflection: the shadows of cubes on a floor, quadrilaterals fitting a square
    face as well as a grey cube's (edge misfit 0.15–0.30 px), are put 1.2–1.4 mirror radii from the
    axis, right in front of the mirror (lighting bench, floor2 case). Where a blob does show there but it
    is the face's own (`own`, its blob mask), over `DIRECT_VIEW_IN_MIRROR` of it covered by the cube's
    direct image, the cube would hide the very reflection that was measured: the blob is a cube seen
    straight, standing over the mirror, not a reflection (one 4 cm across 0.3 m from the axis was read
    as the reflection of one 8 mm across at the mirror's surface)."""
    px, z_cam = camera.project(_cube_vertices(est, up))
    if np.any(z_cam <= 0):
        return None
    h, w = mirror_region.shape
    lo, hi = px.min(axis=0), px.max(axis=0)
    if hi[0] < 0 or hi[1] < 0 or lo[0] >= w or lo[1] >= h:
        return None
    hull = np.zeros((h, w), dtype=np.uint8)
    cv2.fillConvexPoly(hull, np.round(cv2.convexHull(px.astype(np.float32))[:, 0]).astype(np.int32), 1)
    hull = hull.astype(bool)
    hidden = hull & mirror_region
    if hidden.sum() <= DIRECT_VIEW_IN_MIRROR * max(int(hull.sum()), 1):
        return None
    offset = est.center - camera.position
    distance = float(np.linalg.norm(offset))
    t, hit, _, _ = mirror.intersect(camera.position[None], offset[None] / distance)
    if not hit[0] or distance >= t[0]:
        return None
    centre_px, _ = camera.project(est.center[None])
    u, v = centre_px[0]
    if own is not None and (hull & own).sum() > DIRECT_VIEW_IN_MIRROR * max(int(own.sum()), 1):
        return (f"it would stand between the camera and the mirror around ({u:.0f}, {v:.0f}) px and hide its own "
                f"reflection there: a cube seen directly, not reflected")
    seen = float((hidden & blobs).sum()) / float(hidden.sum())
    if seen >= DIRECT_VIEW_SEEN:
        return None
    return (f"it would stand between the camera and the mirror, hiding the mirror around ({u:.0f}, {v:.0f}) px, "
            f"where no such object shows (a shadow?)")


def _side_to_grow(failed) -> int | None:
    """The side of a failed outline across which its face mask is grown to the blob: one with no contrast
    at all, else a left or right one with too few edge points of contrast or too few consistent ones
    (a side face split off by a brightness step too faint to trace, noise s09/0), or None."""
    return failed.no_contrast_side if failed.no_contrast_side is not None else failed.weak_side


def reconstruct(image, camera, mirror, method: str = DEFAULT_METHOD, cube_size: float | None = None,
                progress=None, compressed: bool = False, blur_domain: str = "auto",
                workers: int | None = None, cube_size_std: float | None = None, floor_height: float | None = None,
                floor_std: float | None = None, setup_std=None) -> Reconstruction:
    """Find and estimate every cube in a mirror image.

    Parameters
    ----------
    image : (H, W, 3) uint8 or float64 in [0, 1], sRGB (or as `camera.response` stores light)
    camera : raytrace.camera.PinholeCamera (where its `red` or `blue` channel has a lens of its own, those channels
        are first resampled onto green's rays: `depth.chroma`)
    mirror : raytrace.mirror.CylinderMirror (or any mirror with `intersect`)
    method : "exact" (default), "ddar", "dds", "shape_prior" or "exact_shape_prior" (the cubes are of one
        unknown size: each face is fitted by `exact`, their sizes fused into one (`depth.priors.common_size`),
        and each face fitted again at that size; its σ adds the common size's, carried through the fit)
    cube_size : float, optional — known edge length in metres (not with "exact_shape_prior", which
        estimates it)
    cube_size_std : float, optional — that length's own σ in metres (with `cube_size` and "exact" only): each
        cube's depth and centre σ add it times how far its fit moves per metre of the size
        (`depth.estimate.with_size_std`), and its size σ is it. Default: the size taken as exact.
    progress : callable(done, total), optional: called as each detected blob is outlined, then as each
        face outlined is estimated; `total` is twice the blobs detected (a blob refused at its outline
        counts as estimated then); three times for "exact_shape_prior", whose fits at the common size
        follow (a third of it, whatever number of faces they are)
    compressed : bool — the image went through lossy (JPEG) compression: cubes are detected on
        the `despeckled` image, edges are located on luma (its chroma is subsampled; colour where
        luma shows no edge) and its ringing is not taken for thin strips beside the faces
    blur_domain : "auto" (default), "encoded" or "linear" — where the blur of an image with blurred
        edges acted (`depth.measure.face_outline`): "auto" decides from the image's blurred faces
        pooled (`depth.measure.blur_domain_verdict`: encoded only when they say so clearly, since a
        renderer's pixel filter and optical blur act on linear light). `Reconstruction.blur_domain`
        says what was used.
    workers : int >= 1, optional — processes the faces are outlined and estimated in (forked,
        `depth.workers.fork_map`); default: every available core. The results do not depend on it.
    floor_height : float, optional — the cubes stand on a floor square to the mirror's axis, this far (m) along
        it from the mirror's centre (−mirror.height / 2: the floor the mirror stands on, where `simulate`'s
        ground lies); with method "exact" alone, and no `cube_size`: each face is read by `exact`, then fitted at
        the size that stands its cube on the floor (`depth.estimate.estimate_face_on_floor`). A face's edges fix
        its height over the camera per metre of size well and its scale poorly where it is narrow; the floor
        fixes the scale. A cube whose edges refute that size is refused (it does not stand on the floor).
    floor_std : float, optional — the σ (m) of `floor_height` (with it alone), carried into each depth's σ.
        Default: the floor's height taken as exact.
    setup_std : depth.setup_error.SetupStd, optional — the σ of the setup's own numbers (the camera's place,
        turn, focal lengths and principal point; the mirror's radius, place and axis), carried into each cube's σ
        through `exact`'s fit (methods "exact" and "exact_shape_prior", whose common size moves as the sizes it is
        fused from; with `floor_height`, the floor placed along the mirror's axis moves with the mirror, and each
        size with it): `depth.setup_error`. Each estimate's `setup_std` keeps that
        share apart. Default: the setup taken as exact.
    """
    from depth.measure import BLUR_DOMAINS, checked_images

    if method not in ALL_METHODS:
        raise DepthError(f"method: expected one of {', '.join(ALL_METHODS)}, got {method!r}")
    if method == "exact_shape_prior" and cube_size is not None:
        raise DepthError("cube_size: exact_shape_prior estimates the cubes' common size; with a known size use "
                         "method exact")
    if cube_size_std is not None:
        if not (np.isfinite(cube_size_std) and cube_size_std >= 0):
            raise DepthError(f"cube_size_std: expected a σ of the edge length in metres, >= 0, got {cube_size_std}")
        if cube_size is None or method != "exact":
            raise DepthError("cube_size_std: the σ of a known cube_size, carried through method exact's fit: give "
                             f"cube_size and method exact{'' if cube_size is None else f', not {method}'}")
    if blur_domain not in ("auto",) + BLUR_DOMAINS:
        raise DepthError(f"blur_domain: expected one of auto, {', '.join(BLUR_DOMAINS)}, got {blur_domain!r}")
    floor = _floor(mirror, method, cube_size, floor_height, floor_std)
    if setup_std is not None:
        from depth.setup_error import SetupStd
        if not isinstance(setup_std, SetupStd):
            raise DepthError(f"setup_std: expected a depth.setup_error.SetupStd, got {type(setup_std).__name__}")
        if method not in EXACT_METHODS:
            raise DepthError(f"setup_std: the setup's σ is carried through method exact's fit alone (exact, "
                             f"exact_shape_prior), not {method}'s")
        if not all(hasattr(mirror, key) for key in ("radius", "center", "axis")):
            raise DepthError("setup_std: carried through a cylindrical mirror's radius, centre and axis; this mirror "
                             "has none")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1):
        raise DepthError(f"workers: expected an integer >= 1, got {workers!r}")
    raw = stored = _image_array(image, camera.resolution)
    if getattr(camera, "has_channel_lenses", False):
        # a lens that images red or blue apart from green (`raytrace.chroma`): those channels resampled where they
        # image green's rays, as the camera stores light, before anything reads the image (`depth.chroma`)
        from depth.chroma import aligned_to_green
        raw = stored = aligned_to_green(raw, camera)
    if getattr(camera, "response", None) is not None:
        # a camera that does not store sRGB (`raytrace.response`): its values re-encoded as the sRGB values of
        # their light, which everything below reads; but a JPEG image's cubes are found on its codes as stored,
        # where the coder's artefacts are as it made them (decoded through a flat stretch of the curve they grow
        # in light, and cut faces: `bench_response`'s JPEG readings)
        stored = raw if raw.dtype == np.uint8 else check_image(raw, camera.resolution)
        raw = camera.response.as_srgb(stored)
    # The faces are outlined and estimated by a helper process (`depth.workers.fork_helper`), which imports
    # scipy's modules and the estimators' (0.5–0.6 s) while this process detects the cubes (which needs none
    # of them), then forks the workers: the one `start_helper` forked before the image was read, else on a
    # process's first call one forked now. Else (a process calling again: a script looping over images) the
    # modules are imported in a thread here (which imports nothing meanwhile but these), so that such a
    # process has them from its second call on rather than forking a helper that imports them again each time.
    # The helper reads the image from memory it shares with this process (`SharedMemory`): an 8-bit image
    # is converted to float64 there (and despeckled) after the helper is told of it, which it reads only once
    # the cubes come. The same values as `check_image` and `despeckled` give (an 8-bit image's values come
    # back from float64 to the bit, so it is median-filtered as it is).
    helper, memory = _take_helper()
    try:
        out = [None, None]  # where the image and the despeckled one go: memory shared with the helper, if any
        if helper is not None:
            out = memory.arrays([(raw.shape, np.float64)] * (2 if compressed else 1))
            helper.send((_helper_faces, (memory, raw.shape, camera, mirror, method, cube_size, progress is not None,
                                         compressed, blur_domain, workers, floor, setup_std is not None)))
        img = check_image(raw, camera.resolution, out=out[0])
        found_on = stored if stored is not raw or raw.dtype == np.uint8 else img
        det_img = despeckled(found_on, out=out[-1]) if compressed else img
        scipy_imported = import_in_background(SOLVER_MODULES) if helper is None else None
        # checked here once: not again by each face's outline, silhouette, blur evidence and regrowth
        with checked_images(img, det_img):
            rec = _reconstruct(img, det_img, camera, mirror, method, cube_size, progress, compressed, blur_domain,
                               workers, scipy_imported, helper, raw, floor, setup_std is not None)
        if floor is not None:
            rec = replace(rec, floor=(float(floor_height), floor[1]))
        if cube_size_std:
            carried = [with_size_std(c.estimate, cube_size_std) for c in rec.cubes]
            rec = replace(rec, cubes=[replace(c, estimate=e, depth_std=e.std["z"]) for c, e in zip(rec.cubes, carried)])
        if setup_std is not None:
            from depth.setup_error import with_setup_std
            carried = [with_setup_std(c.estimate, camera, mirror, setup_std) for c in rec.cubes]
            rec = replace(rec, cubes=[replace(c, estimate=e, depth_std=e.std["z"]) for c, e in zip(rec.cubes, carried)],
                          setup_std=setup_std)
        return rec
    finally:
        if helper is not None:
            helper.close()
            memory.close()  # (its arrays stay mapped; the helper has a descriptor of its own)


def _helper_faces(job, relay, inbox) -> Reconstruction:
    """The helper's task (`reconstruct`): the faces of the detections it is sent, as `_faces` finds them. `job`:
    the shared memory holding the image (float64, then the despeckled one for a JPEG), its shape, and
    `reconstruct`'s arguments (progress: whether to relay it); the detections come from the inbox: the
    coloured ones, then the grey ones (`_faces`' `more`)."""
    from depth.measure import checked_images

    memory, shape, camera, mirror, method, cube_size, progress, compressed, blur_domain, workers, floor, slopes = job
    img, *rest = memory.arrays([(shape, np.float64)] * (2 if compressed else 1))
    memory.close()
    det_img = rest[0] if compressed else img
    mask_bits, mask_shape, packed, more = inbox.get()
    mask = np.unpackbits(mask_bits, count=mask_shape[0] * mask_shape[1]).reshape(mask_shape).view(bool)
    with checked_images(img, det_img):
        rec = _faces(img, det_img, camera, mirror, mask, _unpacked(packed, mask_shape), method, cube_size,
                     relay if progress else None, compressed, blur_domain, workers, more=inbox if more else None,
                     floor=floor, slopes=slopes)
    return replace(rec, mirror_mask=None)  # (the parent has it)


def start_helper() -> bool:
    """Fork now the helper the next `reconstruct` call in this process would fork (none where it would not:
    it has forked one already, or cannot), so that it imports its modules while this process goes on
    reading its inputs: `catadioptric reconstruct` calls it before it reads the image and the setup, 0.05–0.1 s
    before `reconstruct` would. That call takes it; one never taken is ended by `stop_helper` (`helper_started`
    calls both), else as this process exits (`depth.workers`). Returns whether a helper is waiting."""
    global _STARTED, _HELPER_FORKED
    if _STARTED is None and not _HELPER_FORKED:
        memory = SharedMemory()
        helper = fork_helper(None, SOLVER_MODULES)
        if helper is None:
            memory.close()
        else:
            _STARTED, _HELPER_FORKED = (helper, memory), True
    return _STARTED is not None


def stop_helper() -> None:
    """End the helper `start_helper` forked, where no `reconstruct` call has taken it."""
    global _STARTED
    if _STARTED is not None:
        (helper, memory), _STARTED = _STARTED, None
        helper.close()
        memory.close()


@contextlib.contextmanager
def helper_started():
    """`start_helper` on entry, `stop_helper` on exit: the helper is forked at once and, where the block never
    reaches `reconstruct` (bad input), ended."""
    start_helper()
    try:
        yield
    finally:
        stop_helper()


def _take_helper():
    """(helper, its shared memory) for this `reconstruct` call: the one `start_helper` forked, else on the
    process's first call one forked now, else (None, None)."""
    global _STARTED
    if _STARTED is None and not _HELPER_FORKED:
        start_helper()
    taken, _STARTED = _STARTED, None
    return taken if taken is not None else (None, None)


_HELPER_FORKED = False  # whether a helper has been forked for `reconstruct` in this process (once)
_STARTED = None  # (helper, shared memory) forked by `start_helper`, not taken by `reconstruct` yet


def _packed(detections) -> list:
    """The detections with their full-image masks cut to their bounding boxes, to cross a pipe (a 2048×1536
    mask is 3 MB); `_unpacked` restores them. A mask with pixels beyond its detection's box goes whole."""
    out = []
    for det in detections:
        u0, v0, u1, v1 = det.bbox

        def cut(m):
            crop = m[v0:v1, u0:u1]
            return ("box", crop.copy()) if np.count_nonzero(crop) == np.count_nonzero(m) else ("whole", m)
        out.append(replace(det, mask=cut(det.mask), front_face_mask=cut(det.front_face_mask),
                           side_face_masks=[cut(m) for m in det.side_face_masks]))
    return out


def _unpacked(packed, shape) -> list:
    """`_packed`'s detections as they were."""
    out = []
    for det in packed:
        u0, v0, u1, v1 = det.bbox

        def whole(m):
            kind, arr = m
            if kind == "whole":
                return arr
            full = np.zeros(shape, dtype=bool)
            full[v0:v1, u0:u1] = arr
            return full
        out.append(replace(det, mask=whole(det.mask), front_face_mask=whole(det.front_face_mask),
                           side_face_masks=[whole(m) for m in det.side_face_masks]))
    return out


READING_MARGIN_PX = 16
"""How far beyond the mirror region `reading_region` reaches: `reconstruct` reads the pixels within a few of the
mirror's rim (its filters' windows); the pixels beyond 4 px of it, replaced by noise, changed none of the quick
reconstruct bench's 10 readings (PNG and JPEG), beyond 0 px one of them."""


def reading_region(camera, mirror) -> np.ndarray:
    """(H, W) bool: the pixels of an image `reconstruct` reads, the mirror region (`raytrace.truth.mirror_mask`, where
    the cubes are searched) and `READING_MARGIN_PX` about it. A raw frame's demosaic need not work beyond it
    (`depth.chroma.from_raw_frame`'s `where`)."""
    from raytrace.truth import mirror_mask
    side = 2 * READING_MARGIN_PX + 1
    return cv2.dilate(mirror_mask(camera, mirror).view(np.uint8), np.ones((side, side), np.uint8)).view(bool)


def _reconstruct(img, det_img, camera, mirror, method, cube_size, progress, compressed, blur_domain, workers,
                 scipy_imported, helper, raw=None, floor=None, slopes=False) -> Reconstruction:
    """`reconstruct` of its checked image `img` (and `det_img`, the one cubes are detected on; `raw`, the image
    as it was given): the mirror region and the cubes detected in it here; their faces by the helper, where
    there is one, else here."""
    from raytrace.truth import mirror_mask
    from depth.measure import detect_cubes

    mask = mirror_mask(camera, mirror)
    if not mask.any():
        raise DepthError("image: the setup's camera sees no mirror")
    # the largest per-channel spread over the mirror (minMaxLoc: ~5× faster than gathering the pixels),
    # each channel copied over the mirror's bounding box only; of an 8-bit image's own values where it was
    # one (`raw`: an eighth of the bytes to copy, 0.04 s less at 2048×1536), whose extremes / 255 are the
    # converted image's to the bit
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    box = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
    in_box = np.ascontiguousarray(mask[box]).view(np.uint8)
    source, unit = (raw, 255.0) if raw is not None and raw.dtype == np.uint8 else (img, 1.0)
    spread = max(hi / unit - lo / unit for lo, hi, _, _ in (
        cv2.minMaxLoc(np.ascontiguousarray(source[box + (k,)]), in_box) for k in range(3)))
    if spread < 2.0 / 255.0:
        raise DepthError("image: no mirror content (the mirror region is uniform)")
    if helper is not None:
        # The coloured cubes go to the helper as soon as they are found, and it outlines and estimates them
        # while the grey search still runs here, on the core its imports have left idle; the grey ones follow
        # (`_faces`' `more`).
        def send(coloured):
            helper.send((np.packbits(mask), mask.shape, _packed(coloured), True))
        detections = detect_cubes(det_img, mask, compressed=compressed, coloured_found=send)
        rec = helper.run(_packed([det for det in detections if det.achromatic]), progress)
        return replace(rec, mirror_mask=mask)
    detections = detect_cubes(det_img, mask, compressed=compressed)
    scipy_imported()  # before any fork
    return _faces(img, det_img, camera, mirror, mask, detections, method, cube_size, progress, compressed,
                  blur_domain, workers, floor=floor, slopes=slopes)


def _faces(img, det_img, camera, mirror, mask, detections, method, cube_size, progress, compressed, blur_domain,
           workers, more=None, floor=None, slopes=False) -> Reconstruction:
    """`reconstruct`'s faces of the detections: each outlined and estimated (in worker processes), or
    refused with the reason. With `more` (a `depth.workers.Inbox`), `detections` are the coloured ones alone,
    sent while the grey search goes on (`detect_cubes`' `coloured_found`), and the grey ones (`_packed`) come
    from `more`: the coloured faces are outlined and estimated meanwhile. `floor`: (a point of the floor, its
    height's σ) where the cubes stand on it (`_floor`): each face read is fitted again there (`on_floor`).
    `slopes`: each `exact` estimate carries its `ray_slopes` (for the setup's σ: `depth.setup_error`)."""
    from raytrace.truth import mirror_rays
    from depth.measure import (FAINT_EDGE_CONTRAST, FAINT_EDGE_READINGS, NECK_REASON, blur_domain_evidence,
                               convex_filled, detection_order, extended_to_blob, face_outline, faint_regrowth,
                               pooled_blur_domain, same_material_faces, weak_ends_trimmed)

    # exact_shape_prior: every face read as `exact` reads it, then fitted again at the common size (`common`)
    one_size, method = method == "exact_shape_prior", "exact" if method == "exact_shape_prior" else method
    refitted = one_size or floor is not None  # each face read is fitted again: at the common size, or on the floor
    steps = 3 if refitted else 2  # (the progress's total: `steps` per detection)

    def rays(px):
        r = mirror_rays(camera, mirror, px)
        return r.points, r.directions

    def unions(det, face_mask, channels, blur):
        """(union mask, its outline) of the face with each touching part of its blob of the same colour
        (`same_material_faces`), largest first, where the union can be outlined."""
        for part in same_material_faces(img, det):
            if not (part & ~face_mask).any():  # already in the face (a union read at its outline)
                continue
            outline = face_outline(img, face_mask | part, thin_strips=thin_strips, channels=channels,
                                   blur_domain=blur, faint_sides=det.achromatic)
            if outline:
                yield face_mask | part, outline

    blobs = np.zeros(mask.shape, dtype=bool)  # every blob's pixels, refused ones too
    grey_found = [det for det in detections if det.achromatic]  # (the grey search's are added as they come)
    for det in detections:
        blobs |= det.mask
    thin_strips = not compressed  # JPEG ringing beside an edge mimics a thin strip

    def regrown(det, fainter=True):
        """An achromatic detection grown across faint edges (`faint_regrowth`), usable and touching no
        other blob but grey ones within its bounds (`GROWN_PART_MARGIN_PX`): each such reading, one per
        (blur, steps) of `FAINT_EDGE_READINGS` in turn (without `fainter`, only those at
        `FAINT_EDGE_CONTRAST`); then the convex hull (`convex_filled`) of the detection itself and of each
        of those readings, where it fills notches the background bit out of the blob. A white or grey cube before a
        background of nearly its brightness may be found as two of its darker faces, each a blob of its own
        (holdout 4040 s1/0: its side face, 9 × 42 px, and its bottom face, 42 × 12 px, below a front face 44 ×
        233 px); grown, either takes in the other, which a neighbouring cube's blob, reaching beyond, is not.
        Both may then be read as the cube: `_faces` keeps one (`_one_per_face`)."""
        gradients = {}  # each window's gradient per blur, shared by the readings at that blur

        def alone(grown):  # usable and touching no other blob but grey ones within its bounds
            if grown is None or grown.reason:
                return False
            ring = cv2.dilate(grown.mask.view(np.uint8), np.ones((5, 5), np.uint8)).view(bool)
            touched = ring & blobs & ~det.mask
            if not touched.any():
                return True
            x0, y0, x1, y1 = grown.bbox
            m = GROWN_PART_MARGIN_PX
            for other in grey_found:
                ox0, oy0, ox1, oy1 = other.bbox
                if ox0 >= x0 - m and oy0 >= y0 - m and ox1 <= x1 + m and oy1 <= y1 + m:
                    touched &= ~other.mask
            return not touched.any()

        readings = [det]
        for smoothing, contrast in FAINT_EDGE_READINGS:
            if not fainter and contrast != FAINT_EDGE_CONTRAST:
                continue
            grown = faint_regrowth(det_img, mask, det, compressed=compressed, smoothing_px=smoothing,
                                   contrast=contrast, gradients=gradients)
            if alone(grown):
                readings.append(grown)
                yield grown
        for reading in readings:
            hull = convex_filled(det_img, mask, reading, compressed=compressed)
            if alone(hull):
                yield hull

    def outlined(det):
        """The detection's front face outlined: (face pixels (N, 2) (u, v), outline, channels, its
        measurement without the blob mask, the grown detection read or None for the one found, its
        `blur_domain_evidence` or None), or the reason it is refused (str). A white or grey cube before
        a background of nearly its brightness may be found as its darker faces alone, which no face
        outline explains: its blob grown across faint edges is read then. (The detection found is not
        handed back: its full-image masks, pickled from the worker processes, came to 47 MB for a
        2048×1536 image's 5 cubes.) A detection refused for its neck alone (`NECK_REASON`) is grown so too: a
        grey side face found alone, its strip broken by the path tracer's noise, narrows there (holdout 9090
        s3/0, a white cube before a floor as bright, its side face a strip 4–6 px wide)."""
        outcome = outline_detection(det)
        if isinstance(outcome, str) and det.achromatic and not (
                (det.reason and det.reason != NECK_REASON) or det.cut_by_mirror_edge or det.occluded):
            for grown in regrown(det):
                again = outline_detection(grown)
                if not isinstance(again, str):
                    return again + (grown, evidence(again[1]))
        return outcome if isinstance(outcome, str) else outcome + (None, evidence(outcome[1]))

    outlined = _guarded(outlined, lambda reason, det: reason)

    def evidence(outline):
        """The blurred face's share of the image's blur-domain verdict, where one is to be reached: here, in
        the worker, rather than all faces' in turn afterwards (0.5 s for a 2048×1536 floor scene's faces)."""
        return blur_domain_evidence(img, outline) if blur_domain == "auto" and outline.blurred else None

    def outline_detection(det):
        """`outlined` of one detection, as it was found."""
        if det.reason or det.cut_by_mirror_edge or det.occluded:
            return det.reason or ("cut by the mirror's edge" if det.cut_by_mirror_edge else "occluded by another cube")
        channels = "luma" if compressed else "colour"  # JPEG: chroma at half resolution
        face_mask = det.front_face_mask
        faint = det.achromatic  # (`face_outline`'s `faint_sides`)
        outline = face_outline(img, face_mask, thin_strips=thin_strips, channels=channels, blur_domain="linear",
                               faint_sides=faint)
        if not outline and compressed:  # luma failed as a whole: colour alone
            channels = "colour"
            outline = face_outline(img, face_mask, thin_strips=thin_strips, blur_domain="linear", faint_sides=faint)
        grown = set()
        while not outline and (side := _side_to_grow(outline)) is not None and side not in grown:
            # a side with no contrast at all was cut inside one uniform region: the outline there is
            # the blob's (`extended_to_blob`), which `exact` fits as the cube's outer contour. A side face
            # lit like the front face and merged with it makes their top and bottom kink where they meet;
            # the edge points follow the kink (only the side's one curve does not), and `exact`'s outline
            # of the merged faces has it. (Such outlines, rms 0.18–0.44 px about one curve, were refused
            # while the estimate of them came out 30 % off.)
            grown.add(side)
            face_mask = extended_to_blob(face_mask, det.mask, side)
            outline = face_outline(img, face_mask, thin_strips=thin_strips, channels=channels, blur_domain="linear",
                                   faint_sides=faint)
        if not outline:
            # a face cut in two by a cast shadow's edge: the union with its other part (`same_material_faces`)
            face_mask, outline = next(unions(det, face_mask, channels, "linear"), (face_mask, outline))
        if not outline:
            return f"face outline: {outline.reason}"
        face_px = _pixels(face_mask)
        return face_px, outline, channels, _bare(_measurement(img, det.mask, outline, face_px, channels, compressed))

    up = getattr(mirror, "axis", None)
    sky = -camera.R[1] if hasattr(camera, "R") else None  # the camera's up: its image rows run down

    def outline_all(dets, report=None):
        """Each detection's face on its own (in worker processes), the larger blobs first."""
        return fork_map(lambda i: outlined(dets[i]), len(dets), workers, cost=[int(det.mask.sum()) for det in dets],
                        progress=report)

    early = [None] * len(detections)  # per detection, its face's estimate made before the grey ones came, or None
    if more is None:
        outcomes = outline_all(detections, None if progress is None
                               else lambda done, _: progress(done, steps * len(detections)))
    else:
        # While the grey search still runs in the parent, the coloured faces are outlined, then estimated as
        # `settled` would (a blurred face's outline waits for the image's blur-domain verdict): in one pool,
        # the outlines first (larger blobs first), then the estimates, the longest expected first among those
        # whose outline has come (`fork_chain`: a worker that ends the last outlines starts an estimate while
        # the other still outlines). (Each face outlined and estimated as one task, handed out by blob size,
        # the faces of s06 left one worker idle for 0.4 s at the end.)
        def plan(i, outcome):  # (expected work, measurement) of a face to estimate now, else None
            if isinstance(outcome, str) or method == "shape_prior" or (blur_domain != "linear" and outcome[1].blurred):
                return None
            return expected_work(outcome[3], method), outcome[3]

        @functools.partial(_guarded, refused=lambda reason, i, meas: None)  # (`settled` tries again, and refuses)
        def first_estimate(i, meas):
            return estimate_face(rays, _attached(meas, detections[i].mask, img), method=method,
                                 cube_size=cube_size, up=up, ray_slopes=slopes)
        outcomes, early = fork_chain(lambda i: outlined(detections[i]), first_estimate, len(detections), plan,
                                     workers, cost=[int(det.mask.sum()) for det in detections])
        grey = _unpacked(more.get(), mask.shape)
        for det in grey:
            blobs |= det.mask
        grey_found += grey
        found = sorted(zip(detections + grey, outcomes + outline_all(grey), early + [None] * len(grey)),
                       key=lambda item: detection_order(item[0]))  # (stably: as `detect_cubes` orders them)
        detections, outcomes, early = (list(column) for column in zip(*found)) if found else ([], [], [])
        if progress is not None:  # the outlines, counted once their total is known
            for done in range(1, len(detections) + 1):
                progress(done, steps * len(detections))
    cubes, refused, measured, blurred, evidences = [], [], [], [], []
    achromatic = set()  # indices into measured of the faces found without colour
    alternatives = {}  # index into measured: (blob mask, face pixels, channels) of a face with two readings
    sources = []  # per measured face: (detection, face mask, channels)
    first = []  # per measured face: its estimate made already (`early`), or None
    domain, any_blurred = blur_domain, False
    for i, (det, outcome) in enumerate(zip(detections, outcomes)):
        if isinstance(outcome, str):
            refused.append(Refusal(det.bbox, outcome))
            continue
        face_px, outline, channels, meas, grown, ev = outcome
        first.append(early[i])  # (a coloured face's: never a grown detection's, which are grey)
        det = det if grown is None else grown
        bbox = det.bbox  # (the mask's bounds; np.nonzero over a 2048×1536 mask took 14 ms)
        face_mask = _mask_of(face_px, mask.shape)
        any_blurred = any_blurred or outline.blurred
        if outline.blurred and domain != "linear":
            blurred.append((len(measured), det, face_mask, channels))
            evidences.append(ev)
        if outline.alternative is not None:  # a one-pixel strip's other reading, for a refused cube
            alternatives[len(measured)] = (det.mask, face_px, channels)
        if det.achromatic:
            achromatic.add(len(measured))
        if outline.faint_side_px.any() and (cleared := _faint_sides_clear(outline, det.mask, blobs)) is not outline:
            # (the worker did not know every blob: the grey ones come while the coloured faces are read)
            outline = cleared
            meas, first[-1] = _measurement(img, det.mask, outline, face_px, channels, compressed), None
        sources.append((det, face_mask, channels))
        measured.append((_attached(meas, det.mask, img), bbox, outline))
    if blurred:
        if domain == "auto":  # the image's blurred faces pooled
            domain = pooled_blur_domain(evidences)  # (`blur_domain_verdict`, each face's part from its worker)
        if domain == "encoded":  # the edges of the blurred faces again, on the encoded values
            def encoded(j):
                k, det, face_mask, channels = blurred[j]
                outline = face_outline(img, face_mask, thin_strips=thin_strips, channels=channels,
                                       blur_domain="encoded", faint_sides=det.achromatic)
                if not outline:  # cannot happen after a linear outline succeeded; keep that one
                    return None
                meas = _measurement(img, det.mask, outline, measured[k][0].face_px, channels, compressed, blobs)
                return _bare(meas), outline
            redone = fork_map(encoded, len(blurred), workers, cost=[int(f.sum()) for _, _, f, _ in blurred])
            for (k, det, _, _), again in zip(blurred, redone):
                if again is not None:
                    measured[k] = (_attached(again[0], det.mask, img), measured[k][1], again[1])

    def verdict(k, est, meas, size=cube_size) -> str | None:
        """Why the estimate of face k (its cube's size known to be `size`, if not None) is refused, or None."""
        if not est:
            return f"{est.method}: {est.reason}"
        if k in achromatic and (shadow := _shadow_reason(rays, meas, est, size, up, img, sky)):
            return shadow
        if inside := _inside_mirror_reason(mirror, est):
            return f"{est.method}: {inside}"
        if direct := _direct_view_reason(camera, mirror, est, mask, blobs, up, own=meas.blob_mask):
            return f"{est.method}: {direct}"
        return None

    def union_reading(k):
        """(estimate, measurement, outline) of face k read as its first union with a touching part of its blob of the
        same colour (`unions`) that no check refuses (`verdict`), or None."""
        det, face_mask, channels = sources[k]
        for union, outline in unions(det, face_mask, channels, "encoded" if domain == "encoded" else "linear"):
            meas = _measurement(img, det.mask, outline, _pixels(union), channels, compressed, blobs)
            est = estimate_face(rays, meas, method=method, cube_size=cube_size, up=up, ray_slopes=slopes)
            if verdict(k, est, meas) is None:
                return est, meas, outline
        return None

    def faintless_reading(k, meas, outline):
        """The estimate of face k measured from `outline` without its faint side face (`FaceOutline.faint_side_px`),
        where its measurement `meas` took one for the cube's back edge and no check refuses that estimate (`verdict`);
        else None."""
        if not outline.faint_side_px.any():
            return None
        det, _, channels = sources[k]
        plain = _measurement(img, det.mask, replace(outline, faint_side_px=np.zeros(2)), meas.face_px, channels,
                             compressed, blobs)
        if all(a is None or b is not None for a, b in zip(meas.back_sides_px, plain.back_sides_px)):
            return None  # (no faint side face among the back edges read)
        return other_reading(k, plain)

    def weak_ends_reading(k, meas, outline):
        """The estimate of face k from `meas` without the edge points at its sides' ends that show too little of
        their side's contrast to lie on its outline (`depth.measure.weak_ends_trimmed`), where there are such points
        and no check refuses that estimate (`verdict`); else None."""
        sides = weak_ends_trimmed(img, outline, sources[k][2])
        return None if sides is None else other_reading(k, replace(meas, sides_px=sides))

    def other_reading(k, meas):
        """The estimate of face k from `meas` where no check refuses it (`verdict`), else None: a reading another's
        σ is to cover (`_covering`), which takes its centre, size and depth alone, so its own σ is left incomplete
        (`estimate_face`'s `defer`: the same estimate without the turn profile)."""
        est = estimate_face(rays, meas, method=method, cube_size=cube_size, up=up, defer=True, ray_slopes=slopes)
        est = est[0] if isinstance(est, tuple) else est
        return est if verdict(k, est, meas) is None else None

    def settled(k, est=None):
        """Face k's (estimate, outline, reason refused or None, bbox, reading); est: a joint estimate
        (shape_prior), taken as it is, else the face is estimated here. The reading, for `common` alone (else
        None): (k, the measurement estimated, bare, and its blob mask packed where it is not face k's blob)."""
        meas, _, outline = measured[k]
        if est is None:
            est = first[k] if first[k] is not None else estimate_face(rays, meas, method=method, cube_size=cube_size,
                                                                      up=up, ray_slopes=slopes)
            if k in alternatives and outline.alternative is not None:  # (an outline redone encoded may have none)
                # one off-colour pixel beside a side along the pixel grid is read as a strip (a side face)
                # where the fit spans the pixel, else as a pixel mixing the face, a narrower strip and the
                # outside; where no cube fits that reading, the other (choosing by the lower misfit
                # instead moved Mitsuba s01/0 from 3.9 to 9.9 %). Where a cube fits both, either may be the
                # one: the strip's reading stands, its σ covering the other's as an even mixture where that lies
                # beyond 2 σ of it (the pixel says nothing of the side face's width: reconstruct bench s08/1, a face
                # 7 px wide whose side face 0.17 px wide darkens its edge column by 3 %, read as a side face 0.91 px
                # wide, 44.6 % off at 2.5 σ, where the mixing pixel's reading is 2.8 % off; within 2 σ the σ reaches
                # the other reading already: a face 12 px wide, 10.9 % off at 1.2 σ, the other 0.7 % off)
                blob, face_px, channels = alternatives[k]
                alt_outline = outline.alternative
                alt_meas = _measurement(img, blob, alt_outline, face_px, channels, compressed, blobs)
                # (its σ completed only where it is taken: its centre alone decides the covering)
                alt = estimate_face(rays, alt_meas, method=method, cube_size=cube_size, up=up, defer=True,
                                    ray_slopes=slopes)
                alt, complete = alt if isinstance(alt, tuple) else (alt, lambda alt=alt: alt)
                if alt and not est:
                    est, meas, outline = complete(), alt_meas, alt_outline
                elif alt and abs(alt.z - est.z) > 2.0 * est.std["z"] and verdict(k, alt, alt_meas) is None:
                    est = _covering(est, alt, 0.5)
        reason = verdict(k, est, meas)
        if not reason and method != "shape_prior" and _bent_side(est) and (rival := union_reading(k)):
            # A shadow's upright edge across the face (the mirror's, under a sun behind it) makes its lit and
            # shadowed parts look like a front and a side face: the part read as the front face alone is a
            # narrower rectangle, read nearer, whose top or bottom the square then misses. Its union with the
            # touching part of the same colour is read too; where the two readings disagree, the one whose
            # edges fit better stands, its σ covering the other (the edges alone do not tell them apart).
            other_est, other_meas, other = rival
            if abs(other_est.z - est.z) > RIVAL_SIGMAS * np.hypot(est.std["z"], other_est.std["z"]):
                if other_est.rms_residual < est.rms_residual:
                    est, meas, outline, other_est = other_est, other_meas, other, est
                est = _covering(est, other_est, 0.5)
        if not reason and method == "exact" and (plain := faintless_reading(k, meas, outline)) is not None:
            # A faint side face is read from a step of a few levels in profiles pooled along the side, and `exact`
            # takes its outer edge for the cube's back edge: where the face read without it fits its edges as well or
            # better, the image does not tell whether it is there, and either reading may be the cube: its σ covers the
            # other, an even mixture (JPEG holdouts: of the faces with a faint side face the truth does not show, 1212
            # all grey s0/3 27.9 % off at −14.6 σ, the other reading 3.7 %; of those with a real one, 1111 s7/3 1.7 %
            # off, the other 54 %, fitting 0.295 against 0.301 px).
            if plain.rms_residual <= est.rms_residual:
                est = _covering(est, plain, 0.5)
        if not reason and method == "exact" and (trimmed := weak_ends_reading(k, meas, outline)) is not None:
            # A side face merged with the front face kinks the outline where they meet, and the points its
            # quadrilateral samples past the kink, over the background, show a fraction of their side's contrast
            # and lie within a pixel of the line they were sampled on, off the outline (`WEAK_END_CONTRAST_SHARE`).
            # They may turn `exact`'s contour reading: holdout 1212 JPEG s3/3 15.0 % off at −9.1 σ, 2.4 % without
            # them. Left out, a few real points are lost too, and so is the turn they fix where the contrast of a side
            # face's edge is low (5050 JPEG s7/0: 7.1 % off, 29 % without them): either reading may be the cube, and
            # the σ covers the other, an even mixture (hundredth session).
            est = _covering(est, trimmed, 0.5)
        if reason and method != "shape_prior" and (whole := union_reading(k)):
            # Where a cast shadow's curved edge cuts the face in two, the front face is only one part of
            # it, which no square face explains (or only one the camera would see directly). Its union
            # with a touching part of the same colour (`same_material_faces`) is the other reading; a
            # merged side, top or bottom face in it is modelled by `exact` as such.
            (est, meas, outline), reason = whole, None
        bbox = measured[k][1]
        if reason and k in achromatic and method != "shape_prior":
            # A white or grey cube before a background of nearly its brightness: only its darker faces
            # were found, and no cube's front face explains them. The blob grown across faint edges
            # (`faint_regrowth`), where it touches no other blob, is the other reading. A region whose
            # outline is no square face's (a shadow's hexagon) is not read at the fainter steps: none
            # of the cubes they found on the holdouts had been refused so, and on the lighting bench's
            # grey floor scenes such regions took half of their calls (21 of 42).
            for grown in regrown(sources[k][0], fainter=not reason.startswith(SHADOW_MISFIT_REASON)):
                out = outline_detection(grown)
                if isinstance(out, str):
                    continue
                _, other, _, other_meas = out
                other_meas = _attached(other_meas, grown.mask, img)
                other_est = estimate_face(rays, other_meas, method=method, cube_size=cube_size, up=up,
                                          ray_slopes=slopes)
                if verdict(k, other_est, other_meas) is None:
                    est, meas, outline, reason, bbox = other_est, other_meas, other, None, grown.bbox
                    break
        if not refitted or reason:
            return est, outline, reason, bbox, None
        own = meas.blob_mask is sources[k][0].mask
        return est, outline, reason, bbox, (k, _bare(meas), None if own else np.packbits(meas.blob_mask))

    settled = _guarded(settled, lambda reason, k, est=None: (FailedEstimate(method, reason), measured[k][2], reason,
                                                             measured[k][1], None))

    def attached(reading):
        """The measurement of a reading of `settled`, with its blob mask."""
        k, meas, packed = reading
        blob = sources[k][0].mask if packed is None else np.unpackbits(
            packed, count=mask.size).reshape(mask.shape).view(bool)
        return _attached(meas, blob, img)

    def refits(fit, readings):
        """`fit(i)` of each of the faces `readings` (`settled`'s), in worker processes: the progress's last step."""
        return fork_map(fit, len(readings), workers, cost=[expected_work(meas, "exact") for _, meas, _ in readings],
                        progress=None if progress is None else lambda done, n: progress(
                            ((steps - 1) * n + done) * len(detections) // n, steps * len(detections)))

    def refit(readings, fused, alone):
        """The faces `readings` (`settled`'s) fitted by `exact` at the common size `fused` (in worker processes): per
        face, its estimate (`at_common_size`; `alone`: per face, its own `exact` reading where its size was set
        aside, else None), or the reason it is refused."""
        fits = refits(lambda i: estimate_face(rays, attached(readings[i]), method="exact", cube_size=fused.size, up=up,
                                              ray_slopes=slopes), readings)
        out = []
        for reading, at, own in zip(readings, fits, alone):
            est = at_common_size(at, fused, own)
            if not est:
                out.append(f"{est.method}: {est.reason}")
            elif reason := verdict(reading[0], at, attached(reading), fused.size):  # (`at`: exact's, as checks read)
                out.append(f"exact_shape_prior: at the common size {fused.size * 1e3:.2f} mm: {reason}")
            else:
                out.append(est)
        return out

    def common(results):
        """`_one_per_face`'s results with each cube read fitted again at the common size of all (exact_shape_prior),
        as `estimate_faces_exact_shape_prior` does; every cube refused where fewer than 2 sizes have a σ."""
        kept = [i for i, r in enumerate(results) if not r[2]]
        common = common_size_of([results[i][0] for i in kept])  # (a face whose size has no σ is fitted at it too)
        if not common:
            return [r if r[2] else (r[0], r[1], f"{common.method}: {common.reason}", r[3], None) for r in results]
        fused, set_aside = common
        alone = [results[i][0] if out else None for i, out in zip(kept, set_aside)]
        sources = fused_from([results[i][0] for i in kept], fused) if slopes else None  # (for the setup's σ)
        out = list(results)
        for i, again in zip(kept, refit([results[i][4] for i in kept], fused, alone)):
            est, outline, _, bbox, _ = results[i]
            if not isinstance(again, str) and sources is not None:
                again = replace(again, common_size_from=sources)
            out[i] = (est, outline, again, bbox, None) if isinstance(again, str) else (again, outline, None, bbox, None)
        return out

    def on_floor(results):
        """`_one_per_face`'s results with each cube read fitted again at the size that stands it on the floor
        (`estimate_face_on_floor`, from its reading here), checked again at that size."""
        kept = [i for i, r in enumerate(results) if not r[2]]
        point, std = floor
        fits = refits(lambda j: estimate_face_on_floor(rays, attached(results[kept[j]][4]), point, up, std,
                                                       alone=results[kept[j]][0], ray_slopes=slopes),
                      [results[i][4] for i in kept])
        out = list(results)
        for i, est in zip(kept, fits):
            reading = results[i][4]
            reason = verdict(reading[0], est, attached(reading), est.size if est else None)
            if reason and est:
                reason = f"on the floor, at {est.size * 1e3:.2f} mm: {reason}"
            _, outline, _, bbox, _ = results[i]
            out[i] = (est, outline, reason, bbox, None)
        return out

    def cast_shadows(results):
        """(`_one_per_face`'s results with every face read whose blob is the shadow another cube read casts on the
        floor refused, {index of each refused so: the middle px of its caster's front face}): darker than the floor
        beside it (`_darker_than_beside`), and overlapping that shadow by `CAST_SHADOW_IOU` or more, the caster at its
        size read or at another within its σ (`_caster_readings`, `_cast_shadow_overlaps`); the greatest overlap
        first, a face refused casting no shadow after. With method exact alone: the shadow a cube casts turns with it,
        and the other methods take each face to face the mirror's axis (shape_prior read a cube of the reconstruct
        bench's s06 as 64.8 mm across, 23.7 mm true, whose face then overlapped another's shadow, read so too, by
        0.76)."""
        if method != "exact":  # (exact_shape_prior's and the floor's faces are here as exact read them)
            return results, {}
        floor_point = _floor_point(mirror, floor)
        kept = [i for i, r in enumerate(results) if not r[2]]
        dark = [i for i in kept if _darker_than_beside(img, sources[i][0].mask, blobs)]
        casters = {j: _caster_readings(results[j][0], up) for j in kept} if dark else {}
        overlaps = {}  # per dark blob: {each other cube read: (the overlap of its shadow, the caster's size there)}
        for i in dark:
            others = [j for j in kept if j != i]
            overlaps[i] = dict(zip(others, _cast_shadow_overlaps(camera, mirror, rays, sources[i][0].mask,
                                                                 [casters[j] for j in others], floor_point, up)))
        out, shadow_of = list(results), {}
        while True:
            (best, size), i, j = max(((o, i, j) for i in overlaps if i in kept for j, o in overlaps[i].items()
                                      if j in kept), default=((0.0, None), None, None), key=lambda t: t[0][0])
            if best < CAST_SHADOW_IOU:
                return out, shadow_of
            est, outline, _, bbox, *reading = out[i]
            caster, caster_outline = out[j][:2]
            u, v = np.mean(_front_face_px(caster, camera, mirror, caster_outline.corners_px), axis=0)
            at = "" if size == caster.size else (f", the cube at {size * 1e3:.2f} mm, its size read "
                                                 f"{caster.size * 1e3:.2f} ± {caster.std['size'] * 1e3:.2f} mm")
            out[i] = (est, outline, f"{est.method}: the shadow the cube read at ({u:.0f}, {v:.0f}) px casts on the "
                      f"floor (darker than the floor beside it, and their overlap {best:.2f} >= {CAST_SHADOW_IOU}"
                      f"{at})", bbox, *reading)
            shadow_of[i] = (float(u), float(v))
            kept.remove(i)

    # the estimates' progress, after the outlines' (the blobs refused at theirs counted as estimated)
    before = len(detections) + len(refused)
    estimated = None if progress is None else lambda done, _: progress(before + done, steps * len(detections))
    if estimated is not None and refused:
        estimated(0, len(measured))
    if method == "shape_prior":
        joint = estimate_faces_shape_prior(rays, [m for m, _, _ in measured])
        results = []
        for k, est in enumerate(joint):
            results.append(settled(k, est))
            if estimated is not None:
                estimated(k + 1, len(measured))
    else:  # each face on its own (in worker processes), the longest expected first
        # (here alone where every face has its estimate already: its verdict takes less than forking workers)
        results = fork_map(settled, len(measured), 1 if all(f is not None for f in first) else workers,
                           cost=[0.0 if f is not None else expected_work(m, method)
                                 for (m, _, _), f in zip(measured, first)],
                           progress=estimated)
    results = _one_per_face(results)
    results, shadow_of = cast_shadows(results)
    if one_size:
        results = common(results)
    elif floor is not None:
        results = on_floor(results)
    if refitted:
        if progress is not None and detections:  # (where no face was fitted at a common size)
            progress(steps * len(detections), steps * len(detections))
    for k, (est, outline, reason, bbox, _) in enumerate(results):
        if reason:
            refused.append(Refusal(bbox, reason, shadow_of.get(k)))
            continue
        depth = float(mirror.distance_to_axis(est.center[None])[0])
        cubes.append(CubeResult(estimate=est, depth=depth, depth_std=float(est.std.get("z", np.nan)),
                                corners_px=_front_face_px(est, camera, mirror, outline.corners_px), bbox=bbox,
                                edge_points=outline.n_points))
    cubes.sort(key=lambda c: c.bbox[0])
    return Reconstruction(method="exact_shape_prior" if one_size else method, cubes=cubes, refused=refused,
                          mirror_mask=mask,
                          blur_domain=domain if any_blurred else None)
