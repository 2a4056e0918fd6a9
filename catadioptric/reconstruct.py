"""`catadioptric reconstruct`: `read_image`, `run_reconstruction`, `result_dict`, `draw_overlay`, `print_table`.

Reads a mirror photograph and its setup, runs `depth.reconstruct`, prints a table and writes the
JSON result of SETUP_FORMAT.md (and optionally an annotated overlay image), all or nothing.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
from pathlib import Path

import cv2
import numpy as np

from catadioptric.errors import CatadioptricError
from catadioptric.outputs import OutputSet
from catadioptric.setup import load_setup

__all__ = ["decode_image_file", "read_image", "camera_image", "raw_demosaic", "as_codes", "default_setup_path",
           "run_reconstruction", "result_dict", "draw_overlay", "print_table", "write_outputs"]


def is_jpeg(path) -> bool:
    """The file starts with the JPEG start-of-image marker (FF D8 FF), whatever its name."""
    with open(path, "rb") as f:
        return f.read(3) == b"\xff\xd8\xff"


@contextlib.contextmanager
def _stderr_silenced():
    """File descriptor 2 pointed at the null device meanwhile: C libraries write there, not to `sys.stderr`."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def decode_image_file(path, flags=cv2.IMREAD_UNCHANGED, expected="an 8-bit RGB PNG or JPEG") -> np.ndarray:
    """The image file at `path` decoded by `cv2.imdecode` with `flags` (as stored by default: OpenCV's channel
    order, any depth); one-line errors for a missing, empty or undecodable file or a folder, the last saying what
    was `expected`. What the decoders print on a broken file (libpng's "PNG input buffer is incomplete", OpenCV's
    warnings) is kept off the process's stderr: the error says it instead."""
    path = Path(path)
    if not path.exists():
        raise CatadioptricError(f"{path}: no such image file")
    data = np.fromfile(path, dtype=np.uint8) if path.is_file() else None
    if data is None or data.size == 0:
        raise CatadioptricError(f"{path}: expected an image file, got {'a folder' if path.is_dir() else 'an empty file'}")
    with _stderr_silenced():
        img = cv2.imdecode(data, flags)
    if img is None:
        raise CatadioptricError(f"{path}: cannot read the image (expected {expected})")
    return img


def read_image(path) -> np.ndarray:
    """An 8-bit RGB image file as (H, W, 3) uint8; one-line errors for anything else."""
    path = Path(path)
    return _rgb_image(decode_image_file(path), path)


def camera_image(path, setup, setup_path, demosaic: str | None = None) -> np.ndarray:
    """The image file at `path` as `reconstruct` reads it for `setup`'s camera: an 8-bit RGB image as (H, W, 3)
    uint8, or where `[camera] mosaic` says the camera's images are raw Bayer frames, the frame checked and
    demosaiced (`depth.chroma.from_raw_frame`, by `demosaic`: default `depth.chroma.DEMOSAIC`) as 8-bit codes to draw
    on (`reconstruct` reads its values unrounded); checked to be of the setup's camera.resolution; one-line errors
    naming the file for anything else."""
    path = Path(path)
    return as_codes(_camera_image(decode_image_file(path), path, setup, setup_path, demosaic))


def as_codes(image: np.ndarray) -> np.ndarray:
    """An image as 8-bit codes (H, W, 3) uint8 for drawing on: as it is, or float64 values in [0, 1] rounded."""
    if image.dtype == np.uint8:
        return image
    return np.round(np.clip(image, 0.0, 1.0) * 255.0).astype(np.uint8)


def raw_demosaic(setup, demosaic: str | None = None) -> str | None:
    """The demosaic a raw Bayer frame of `setup`'s camera is read through (`demosaic`, default
    `depth.chroma.DEMOSAIC`), or None where its images are RGB (no `[camera] mosaic`)."""
    if setup.camera.mosaic is None:
        return None
    from depth.chroma import DEMOSAIC
    return demosaic or DEMOSAIC


def _camera_image(decoded, path, setup, setup_path, demosaic=None) -> np.ndarray:
    """`camera_image` of the file's decoded values (`decode_image_file`'s)."""
    pattern = setup.camera.mosaic
    if pattern is None:
        return _sized(_rgb_image(decoded, path), path, setup, setup_path)
    key = f"{setup_path}: camera.mosaic {pattern}"
    if decoded.ndim == 3 and decoded.shape[2] != 1:
        raise CatadioptricError(f"{path}: expected a one-channel raw Bayer frame ({key}), got an image of "
                                f"{decoded.shape[2]} channels")
    if decoded.dtype not in (np.uint8, np.uint16):
        kind = "floats" if decoded.dtype.kind == "f" else "integers"
        raise CatadioptricError(f"{path}: expected an 8- or 16-bit raw Bayer frame ({key}), got "
                                f"{decoded.dtype.itemsize * 8}-bit {kind}")
    if is_jpeg(path):
        raise CatadioptricError(f"{path}: expected a raw Bayer frame stored losslessly, PNG or TIFF ({key}), "
                                "got a JPEG file")
    frame = _sized(decoded.reshape(decoded.shape[:2]), path, setup, setup_path)  # (before it is demosaiced)
    cam = setup.camera
    most = np.iinfo(frame.dtype).max
    if cam.black_level >= most or (cam.white_level or 0) > most:
        level = "white_level" if (cam.white_level or 0) > most else "black_level"
        bits = frame.dtype.itemsize * 8
        raise CatadioptricError(f"{path}: {'an' if bits == 8 else 'a'} {bits}-bit frame's values reach {most}, under "
                                f"{setup_path}: camera.{level} {getattr(cam, level):g}")
    from depth.chroma import from_raw_frame
    from depth.reconstruct import reading_region
    return from_raw_frame(frame, pattern, raw_demosaic(setup, demosaic), cam.black_level, cam.white_level,
                          cam.white_balance, where=reading_region(cam.build(), setup.mirror.build()))


def _sized(image, path, setup, setup_path) -> np.ndarray:
    """The image, checked to be of the setup's camera.resolution (one-line error naming both files)."""
    w, h = setup.camera.resolution
    if image.shape[:2] != (h, w):
        raise CatadioptricError(f"{path}: expected {w}×{h} pixels ({setup_path}: camera.resolution), "
                                f"got {image.shape[1]}×{image.shape[0]}")
    return image


def _rgb_image(img, path) -> np.ndarray:
    """An 8-bit RGB image's decoded values (OpenCV's channel order) as (H, W, 3) uint8 RGB; one-line errors."""
    if img.ndim == 2 or img.shape[2] == 1:
        raise CatadioptricError(f"{path}: expected an RGB colour image, got a grayscale image (a camera's raw Bayer "
                                "frame? its setup says so: [camera] mosaic)")
    if img.dtype != np.uint8:
        raise CatadioptricError(f"{path}: expected an 8-bit image, got {img.dtype.itemsize * 8}-bit")
    if img.shape[2] == 4:
        img = img[:, :, :3]
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def default_setup_path(image_path) -> Path:
    """IMAGE.toml beside IMAGE.png."""
    return Path(image_path).with_suffix(".toml")


def run_reconstruction(image_path, setup_path=None, method=None, cube_size=None, progress=None, blur_domain=None,
                       workers=None, cube_size_std=None, on_floor=False, floor_height=None, floor_std=None,
                       demosaic=None):
    """Validate the inputs and reconstruct (the faces on `workers` processes, default every core); returns
    (setup, setup_path, image, Reconstruction). `on_floor`: the cubes stand on the floor the mirror stands on
    (its lower end); `floor_height`: on a floor this far (m) along the mirror's axis from its centre instead;
    `floor_std`: that floor's height σ (m); `demosaic`: how a raw Bayer frame is made an image (`raw_demosaic`)."""
    from depth.reconstruct import helper_started
    # `reconstruct`'s helper process forked first, before any thread starts here: it imports the estimators'
    # modules (0.5–0.6 s) while the inputs are read and the cubes detected; ended where the inputs are refused
    with helper_started():
        return _run_reconstruction(image_path, setup_path, method, cube_size, progress, blur_domain, workers,
                                   cube_size_std, on_floor, floor_height, floor_std, demosaic)


def _check_floor(method, cube_size, on_floor, floor_height, floor_std):
    """The one-line error for floor arguments the command cannot take, if any."""
    if on_floor and floor_height is not None:
        raise CatadioptricError("--on-floor, --floor-height: give one (--on-floor: the floor the mirror stands on)")
    if floor_height is not None and not np.isfinite(floor_height):
        raise CatadioptricError(f"--floor-height: expected a height in metres along the mirror's axis from its "
                                f"centre, got {floor_height}")
    flag = "--on-floor" if on_floor else "--floor-height"
    if floor_std is not None:
        if not (np.isfinite(floor_std) and floor_std >= 0):
            raise CatadioptricError("--floor-std: expected the σ of the floor's height in metres, >= 0, "
                                    f"got {floor_std}")
        if not on_floor and floor_height is None:
            raise CatadioptricError("--floor-std: the σ of the floor's height: give --on-floor or --floor-height")
    if on_floor or floor_height is not None:
        if method != "exact":
            raise CatadioptricError(f"{flag}: cubes standing on a floor are fitted by --method exact, not {method}")
        if cube_size is not None:
            raise CatadioptricError(f"{flag}: the floor fixes each cube's size; give it or --cube-size, not both")


def _run_reconstruction(image_path, setup_path, method, cube_size, progress, blur_domain, workers, cube_size_std,
                        on_floor=False, floor_height=None, floor_std=None, demosaic=None):
    from concurrent.futures import ThreadPoolExecutor
    with ThreadPoolExecutor(1) as reader:
        # the image decoded (by OpenCV, which lets go of the GIL: 40 ms for a 2048×1536 PNG) while the
        # modules below are imported; its errors are raised in turn, below
        reading = reader.submit(decode_image_file, Path(image_path))
        from depth.measure import BLUR_DOMAINS
        from depth.reconstruct import ALL_METHODS, DEFAULT_METHOD, EXACT_METHODS, reconstruct
    method = method or DEFAULT_METHOD
    if method not in ALL_METHODS:
        raise CatadioptricError(f"--method: expected one of {', '.join(ALL_METHODS)}, got {method!r}")
    blur_domain = blur_domain or "auto"
    if blur_domain not in ("auto",) + BLUR_DOMAINS:
        raise CatadioptricError(f"--blur-domain: expected one of auto, {', '.join(BLUR_DOMAINS)}, got {blur_domain!r}")
    if cube_size is not None and not (np.isfinite(cube_size) and cube_size > 0):
        raise CatadioptricError(f"--cube-size: expected a positive edge length in metres, got {cube_size}")
    if cube_size is not None and method == "exact_shape_prior":
        raise CatadioptricError("--cube-size: exact_shape_prior estimates the cubes' common size; with a known "
                                "size use --method exact")
    if cube_size_std is not None and not (np.isfinite(cube_size_std) and cube_size_std >= 0):
        raise CatadioptricError(f"--cube-size-std: expected the σ of the edge length in metres, >= 0, "
                                f"got {cube_size_std}")
    if cube_size_std is not None and (cube_size is None or method != "exact"):
        raise CatadioptricError("--cube-size-std: the σ of a known --cube-size, carried through the exact "
                                "estimator's fit: give --cube-size and --method exact"
                                + ("" if cube_size is None else f", not {method}"))
    _check_floor(method, cube_size, on_floor, floor_height, floor_std)
    from depth.chroma import DEMOSAICS
    if demosaic is not None and demosaic not in DEMOSAICS:
        raise CatadioptricError(f"--demosaic: expected one of {', '.join(DEMOSAICS)}, got {demosaic!r}")
    setup_path = Path(setup_path) if setup_path else default_setup_path(image_path)
    decoded = reading.result()
    setup = load_setup(setup_path)
    if demosaic is not None and setup.camera.mosaic is None:
        raise CatadioptricError(f"--demosaic: {setup_path} has no [camera] mosaic: its camera's images are RGB, not "
                                "raw Bayer frames")
    image = _camera_image(decoded, Path(image_path), setup, setup_path, demosaic)
    from depth.errors import DepthError
    if on_floor:
        floor_height = -setup.mirror.height / 2.0
    carried = setup.uncertainty is not None and method in EXACT_METHODS
    try:
        rec = reconstruct(image, setup.camera.build(), setup.mirror.build(), method=method,
                          cube_size=cube_size, progress=progress,
                          # a demosaiced image's red and blue are interpolated over 3 pixels of 4, as a JPEG's
                          # chroma is subsampled: read as one is, its edges on luma (`bench_bayer`); so is a raw
                          # frame's, demosaiced above
                          compressed=(is_jpeg(image_path) or setup.camera.demosaiced
                                      or setup.camera.mosaic is not None),
                          blur_domain=blur_domain, workers=workers, cube_size_std=cube_size_std,
                          floor_height=floor_height, floor_std=floor_std,
                          setup_std=setup.uncertainty.build() if carried else None)
    except DepthError as exc:
        raise CatadioptricError(f"{image_path}: {exc}") from None
    return setup, setup_path, as_codes(image), rec


def result_dict(image_path, setup_path, rec, demosaic: str | None = None) -> dict:
    """The reconstruct result of SETUP_FORMAT.md (plus `refused`, the method used, when faces were blurred
    `blur_domain`, when the cubes were taken to stand on a floor `floor`: its height along the mirror's axis
    from the mirror's centre and that height's σ, metres, and when the image was a raw Bayer frame the `demosaic`
    that made it an image)."""
    out = {"image": Path(image_path).name, "setup": Path(setup_path).name, "method": rec.method,
           "cubes": [c.to_dict() for c in rec.cubes], "refused": [r.to_dict() for r in rec.refused]}
    if demosaic is not None:  # a raw Bayer frame: how it was made an image (`raw_demosaic`)
        out["demosaic"] = demosaic
    if rec.blur_domain is not None:  # blurred faces: where their blur was taken to act
        out["blur_domain"] = rec.blur_domain
    if getattr(rec, "floor", None) is not None:  # the floor the cubes were taken to stand on
        out["floor"] = {"height": rec.floor[0], "std": rec.floor[1]}
    if getattr(rec, "setup_std", None) is not None:  # the setup's σ carried into the cubes' (its non-zero keys)
        out["setup_uncertainty"] = dict(rec.setup_std.items())
    return out


def setup_uncertainty_note(setup, result: dict, setup_path) -> str | None:
    """The line saying that the setup's `[uncertainty]` was not carried into the σ (with a method other than
    `exact` and `exact_shape_prior`), else None."""
    if setup.uncertainty is None or "setup_uncertainty" in result:
        return None
    return (f"note: {setup_path}'s [uncertainty] is carried through method exact's fit alone (exact, "
            f"exact_shape_prior; not method {result['method']}'s): the ±σ above count the image's noise alone")


OVERLAY_FACE = (255, 255, 0)
"""Colour (RGB) of a face outline on the overlay."""
OVERLAY_FLAGGED = (255, 140, 0)
"""Colour (RGB) of a face outline whose edges no square explains well (`depth.estimate.EDGE_MISFIT_WARN_PX`)."""


def draw_overlay(image: np.ndarray, rec) -> np.ndarray:
    """The image with each face outline, its corners and its depth drawn on it, each refused blob boxed (a cast
    shadow labelled so, with a line to the cube casting it) : (H, W, 3) uint8 RGB.

    `rec`: a `depth.reconstruct.Reconstruction`, or anything with its `mirror_mask`, `refused` (each with
    `bbox`, and optionally `shadow_of_px`) and `cubes` (each with `corners_px`, `bbox`, `depth` and, optionally,
    `edge_misfit_px`)."""
    out = image.copy()
    outline = cv2.dilate(rec.mirror_mask.astype(np.uint8), np.ones((3, 3), np.uint8)) - rec.mirror_mask.astype(np.uint8)
    out[outline > 0] = (255, 255, 255)
    from depth.estimate import edge_misfit_flagged
    scale = 8  # sub-pixel drawing: coordinates in 1/8 px
    for c in rec.cubes:
        # a fit whose edges miss its face by more than EDGE_MISFIT_WARN_PX rms: orange, and "!" by its depth
        flagged = edge_misfit_flagged(getattr(c, "edge_misfit_px", None))
        pts = np.round((c.corners_px + 0.5) * scale - 0.5).astype(np.int32)  # pixel centres → cv2 coords
        cv2.polylines(out, [pts.reshape(-1, 1, 2)], True, OVERLAY_FLAGGED if flagged else OVERLAY_FACE, 1,
                      cv2.LINE_AA, shift=3)
        for p in pts:
            cv2.circle(out, tuple(int(v) for v in p), 3 * scale, (255, 0, 255), 1, cv2.LINE_AA, shift=3)
        x0, y0 = c.bbox[0], max(c.bbox[1] - 8, 12)
        label = f"{c.depth:.3f} m" + (" !" if flagged else "")
        cv2.putText(out, label, (x0, y0), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 3, cv2.LINE_AA)
        cv2.putText(out, label, (x0, y0), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
    for r in rec.refused:
        x0, y0, x1, y1 = r.bbox
        cv2.rectangle(out, (x0, y0), (x1, y1), (255, 60, 60), 1)
        caster = getattr(r, "shadow_of_px", None)
        cv2.putText(out, "refused" if caster is None else "shadow", (x0, max(y0 - 6, 12)), cv2.FONT_HERSHEY_SIMPLEX,
                    0.4, (255, 60, 60), 1, cv2.LINE_AA)
        if caster is not None:  # a cast shadow: a line from the middle of its box to the face of its caster
            ends = np.round((np.array([((x0 + x1) / 2, (y0 + y1) / 2), caster]) + 0.5) * scale - 0.5).astype(np.int32)
            cv2.line(out, tuple(int(v) for v in ends[0]), tuple(int(v) for v in ends[1]), (255, 60, 60), 1,
                     cv2.LINE_AA, shift=3)
    return out


def print_table(console, result: dict, truth: dict | None = None) -> None:
    """A rich table of the cubes (with errors against `truth` cubes when given)."""
    from rich.table import Table

    from depth.estimate import EDGE_MISFIT_WARN_PX, edge_misfit_flagged
    floor = result.get("floor")
    on_floor = "" if floor is None else (f", standing on a floor {floor['height']:+.4f} m along the mirror's axis"
                                         + (f" (±{floor['std']:.4f})" if floor["std"] else ""))
    carried = ", ±σ with the setup's uncertainty" if "setup_uncertainty" in result else ""
    t = Table(title=f"{result['image']}: {len(result['cubes'])} cube(s), method {result['method']}{on_floor}{carried}")
    cols = ["#", "depth (m)", "±σ (m)", *(["setup σ"] if carried else []), "size (m)", "centre (m)", "AR r_i",
            "misfit"]
    if truth:
        cols += ["true depth", "centre err", "size err"]
    for c in cols:
        t.add_column(c, justify="right", no_wrap=c == "centre (m)")  # a 3-vector reads badly split
    matches = match_truth(result, truth) if truth else [None] * len(result["cubes"])
    misfits = [c.get("edge_misfit_px") for c in result["cubes"]]  # `exact`'s; None for the other methods
    flags = [edge_misfit_flagged(m) for m in misfits]
    for i, (c, tc, misfit, flagged) in enumerate(zip(result["cubes"], matches, misfits, flags)):
        row = [str(i), f"{c['depth']:.4f}", f"{c['uncertainty']['depth']:.4f}",
               *([f"{c['uncertainty_from_setup']['depth']:.4f}"] if carried else []),
               f"{c['size']:.4f}" + (" *" if c.get("size_set_aside") else ""),
               "[" + ", ".join(f"{x:+.3f}" for x in c["center"]) + "]", f"{c['aspect_ratio']:.3f}",
               "—" if misfit is None else f"{misfit:.2f}" + (" !" if flagged else "")]
        if truth:
            if tc is None:
                row += ["—", "—", "—"]
            else:
                err = np.linalg.norm(np.subtract(c["center"], tc["center"])) / tc["depth"]
                row += [f"{tc['depth']:.4f}", f"{100 * err:.2f} %", f"{100 * (c['size'] / tc['size'] - 1):+.2f} %"]
        t.add_row(*row)
    if any(m is not None for m in misfits):
        t.caption = "misfit: rms distance (px) of the face's edge points from the fitted square"
    if carried:
        share = "setup σ: the share (m) of ±σ the setup's uncertainty gives"
        t.caption = f"{t.caption}; {share}" if t.caption else share
    console.print(t)
    if any(flags):
        console.print(f"! the face's edges miss the fitted square by more than {EDGE_MISFIT_WARN_PX} px rms: "
                      "its outline is likely off somewhere and ±σ may be short")
    if note := size_set_aside_note(result["cubes"]):
        console.print(note)
    for r in result.get("refused", []):
        console.print(f"refused cube at {r['bbox_px']}: {r['reason']}")


FLOOR_NOTE_SIGMAS = 2.0
"""`floor_note`: each cube's bottom lies within this many σ of the floor the mirror stands on. `exact`'s readings of
`python -m bench on_floor`'s images (cubes standing on that floor): the note in 37 of 40 (clean, noise and JPEG 11 of
12 each, Mitsuba 4 of 4; the largest ratio 0.02–0.50 on the clean ones, and 4.9, 25.8 and 40.5 where it is missing:
twice a cube `exact` invents beside the mirror); of the reconstruct bench's (cubes floating 5.7 cm or more over
it), in none of 63 (its largest ratio 2.9–273 on the clean ones)."""


def floor_note(result: dict, mirror) -> str | None:
    """The line that says the cubes `exact` read from their own edges may stand on the floor the mirror (`mirror`:
    its setup's, with `center`, `axis` and `height`) stands on, so that `--on-floor` would fix their scale: every
    cube's bottom within `FLOOR_NOTE_SIGMAS` σ of that floor (σ: the centre's and half the size's, in
    quadrature). None otherwise, and for a result read on a floor, at a known size (size σ 0) or by another
    method."""
    cubes = result.get("cubes", [])
    if result.get("method") != "exact" or result.get("floor") is not None or not cubes:
        return None
    axis = np.asarray(mirror.axis, dtype=np.float64) / np.linalg.norm(mirror.axis)
    floor = np.asarray(mirror.center, dtype=np.float64) - axis * mirror.height / 2.0
    gaps, sds = [], []
    for c in cubes:
        u = c.get("uncertainty", {})
        if not u.get("size"):  # a known size: not the edges' own
            return None
        gaps.append(float((np.asarray(c["center"]) - floor) @ axis) - c["size"] / 2.0)
        sds.append(float(np.hypot(u.get("center", np.inf), u["size"] / 2.0)))
    gaps, sds = np.array(gaps), np.array(sds)
    if not np.all(np.abs(gaps) <= FLOOR_NOTE_SIGMAS * sds):
        return None
    each = ", ".join(f"#{i} {1e3 * g:+.1f} ± {1e3 * sd:.1f} mm" for i, (g, sd) in enumerate(zip(gaps, sds)))
    return (f"the cubes' bottoms lie within {FLOOR_NOTE_SIGMAS:g} σ of the floor the mirror stands on ({each}): if "
            "they stand on it, --on-floor fixes each one's scale, which a narrow face's edges hardly do")


def size_set_aside_note(cubes: list) -> str | None:
    """The line that says which result cubes (`exact_shape_prior`'s) had their own size set aside from the common
    size, and what that means; None where none had."""
    aside = [f"#{i}" for i, c in enumerate(cubes) if c.get("size_set_aside")]
    if not aside:
        return None
    from depth.priors import COMMON_SIZE_REJECT
    return (f"* {', '.join(aside)}: its own size lay over {COMMON_SIZE_REJECT:g} σ from the others' and was left out "
            "of their common size; read at it all the same, its ±σ covers its own reading too. Are the cubes all "
            "one size?")


def match_truth(result: dict, truth: dict) -> list:
    """For each result cube, the truth cube whose face-corner centroid is nearest in the image (≤ 20 px)."""
    out = []
    tcs = truth.get("cubes", [])
    for c in result["cubes"]:
        m = np.mean(c["front_face_corners_px"], axis=0)
        best, dist = None, 20.0
        for tc in tcs:
            px = np.asarray(tc["front_face_corners_px"], dtype=float)
            if not np.all(np.isfinite(px)):
                continue
            d = np.linalg.norm(px.mean(axis=0) - m)
            if d < dist:
                best, dist = tc, d
        out.append(best)
    return out


def write_outputs(result: dict, json_path, overlay_path=None, overlay: np.ndarray | None = None) -> list:
    """Write the JSON result (and the overlay PNG) together."""
    with OutputSet() as out:
        out.write_text(json_path, json.dumps(result, indent=2) + "\n")
        if overlay_path is not None:
            from catadioptric.simulate import encode_png
            out.write_bytes(overlay_path, encode_png(overlay))
    return [Path(json_path)] + ([Path(overlay_path)] if overlay_path is not None else [])
